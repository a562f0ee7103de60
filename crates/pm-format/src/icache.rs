//! The irradiance-cache file: the records of one image's irradiance-cache prepass
//! (Ward and Heckbert 1992), so that tiles rendered in separate processes share one
//! cache and together equal the whole image.
//!
//! The file is [`crate::framed`]'s frame (magic `b"PMICACHE"`, version 1,
//! records of 112 bytes, count zero, source hash the payload hash of the global
//! photon map gathered from, params the settings that shaped the cache as
//! "name=value" words). Records are [`CacheRecord`]s.

use crate::FormatError;
use crate::framed::{self, Fields, Kind};
use bytemuck::{Pod, Zeroable};
use std::path::Path;

/// File signature.
pub const CACHE_MAGIC: [u8; 8] = *b"PMICACHE";
/// The only version this build reads and writes.
pub const CACHE_VERSION: u32 = 1;
const KIND: Kind = Kind {
    magic: CACHE_MAGIC,
    version: CACHE_VERSION,
    record_size: size_of::<CacheRecord>(),
    name: "irradiance cache",
};

/// One irradiance-cache record (112 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct CacheRecord {
    /// Position \[m\].
    pub p: [f32; 3],
    /// Unit surface normal.
    pub n: [f32; 3],
    /// Indirect irradiance E [W m^-2 per channel].
    pub e: [f32; 3],
    /// Radius of validity R \[m\].
    pub r: f32,
    /// Translational gradient dE/dx [W m^-3], x y z per channel (R, G, B).
    pub grad_t: [f32; 9],
    /// Rotational gradient [W m^-2 rad^-1], x y z per channel.
    pub grad_r: [f32; 9],
}

/// An irradiance-cache file in memory.
#[derive(Clone, Debug, PartialEq)]
pub struct CacheFile {
    /// Width of the image the prepass covered \[pixels\].
    pub width: u32,
    /// Height \[pixels\].
    pub height: u32,
    /// blake3 of the scene.
    pub scene_hash: [u8; 32],
    /// Payload hash of the global photon map the final gathers read.
    pub map_hash: [u8; 32],
    /// The settings that shaped the cache (JSON text).
    pub params: String,
    /// Records in insertion order.
    pub records: Vec<CacheRecord>,
}

/// Write `c` to `path` atomically.
pub fn write_cache(path: &Path, c: &CacheFile) -> Result<(), FormatError> {
    let fields = Fields {
        width: c.width,
        height: c.height,
        count: 0,
        scene_hash: c.scene_hash,
        source_hash: c.map_hash,
        params: c.params.clone(),
    };
    framed::write(path, &KIND, &fields, bytemuck::cast_slice(&c.records))
}

/// Read and check an irradiance-cache file.
pub fn read_cache(path: &Path) -> Result<CacheFile, FormatError> {
    let (f, payload) = framed::read(path, &KIND)?;
    let records: Vec<CacheRecord> = payload.chunks_exact(KIND.record_size).map(bytemuck::pod_read_unaligned).collect();
    for (i, r) in records.iter().enumerate() {
        let finite = r.p.iter().chain(&r.n).chain(&r.e).chain(&r.grad_t).chain(&r.grad_r).all(|v| v.is_finite());
        if !finite || !(r.r > 0.0) || !r.r.is_finite() || r.e.iter().any(|&e| e < 0.0) {
            return Err(framed::bad_record(
                path,
                &KIND,
                i,
                "holds a non-finite value, a negative irradiance or a radius <= 0",
            ));
        }
    }
    Ok(CacheFile {
        width: f.width,
        height: f.height,
        scene_hash: f.scene_hash,
        map_hash: f.source_hash,
        params: f.params,
        records,
    })
}
