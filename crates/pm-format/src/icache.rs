//! The irradiance-cache file: the records of one image's irradiance-cache prepass
//! (Ward and Heckbert 1992), so that tiles rendered in separate processes share one
//! cache and together equal the whole image.
//!
//! ```text
//! offset size field
//!      0    8 magic            b"PMICACHE"
//!      8    4 version          u32, must be 1
//!     12    4 header_len       u32: bytes before the first record; multiple of 16
//!     16    4 record_size      u32, must be 112
//!     20    4 width            u32: the image the prepass covered [pixels]
//!     24    4 height           u32 [pixels]
//!     28    4 reserved         zero
//!     32    8 n_records        u64
//!     40   32 scene_hash       blake3 of the scene file and its buffers
//!     72   32 map_hash         payload hash of the global photon map gathered from
//!    104   32 payload_hash     blake3 of the record bytes
//!    136    4 params_len       u32
//!    140    n params           UTF-8 (JSON): the settings that shaped the cache
//!      .    . zero padding
//! len-8    8 header_check     first 8 bytes of blake3(header bytes before this field)
//! ```
//! All integers and floats are little-endian. Records are [`CacheRecord`]s.

use crate::header::{FormatError, Problem, check_ok, framed_len, header_len_ok, params_text, seal};
use bytemuck::{Pod, Zeroable};
use std::io::{Read, Write};
use std::path::Path;

/// File signature.
pub const CACHE_MAGIC: [u8; 8] = *b"PMICACHE";
/// The only version this build reads and writes.
pub const CACHE_VERSION: u32 = 1;
const FIXED_LEN: usize = 140;

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

fn fail(path: &Path, problem: Problem) -> FormatError {
    FormatError { path: path.to_owned(), problem }
}

/// Write `c` to `path` atomically.
pub fn write_cache(path: &Path, c: &CacheFile) -> Result<(), FormatError> {
    let payload: &[u8] = bytemuck::cast_slice(&c.records);
    let params = c.params.as_bytes();
    let header_len = framed_len(FIXED_LEN, params.len());
    let mut b = Vec::with_capacity(header_len);
    b.extend_from_slice(&CACHE_MAGIC);
    b.extend_from_slice(&CACHE_VERSION.to_le_bytes());
    b.extend_from_slice(&(header_len as u32).to_le_bytes());
    b.extend_from_slice(&(size_of::<CacheRecord>() as u32).to_le_bytes());
    b.extend_from_slice(&c.width.to_le_bytes());
    b.extend_from_slice(&c.height.to_le_bytes());
    b.extend_from_slice(&0u32.to_le_bytes());
    b.extend_from_slice(&(c.records.len() as u64).to_le_bytes());
    b.extend_from_slice(&c.scene_hash);
    b.extend_from_slice(&c.map_hash);
    b.extend_from_slice(blake3::hash(payload).as_bytes());
    b.extend_from_slice(&(params.len() as u32).to_le_bytes());
    debug_assert_eq!(b.len(), FIXED_LEN);
    seal(&mut b, params, header_len);
    crate::write_atomically(path, |w| {
        w.write_all(&b)?;
        w.write_all(payload)
    })
    .map_err(|e| fail(path, Problem::Io(e)))
}

/// Read and check an irradiance-cache file.
pub fn read_cache(path: &Path) -> Result<CacheFile, FormatError> {
    let err = |p| fail(path, p);
    let mut bytes = Vec::new();
    std::fs::File::open(path).and_then(|mut f| f.read_to_end(&mut bytes)).map_err(|e| err(Problem::Io(e)))?;
    let len = bytes.len() as u64;
    if bytes.len() < FIXED_LEN + 8 {
        return Err(err(Problem::NotCache { what: format!("only {len} bytes") }));
    }
    let u32_at = |o: usize| u32::from_le_bytes(bytes[o..o + 4].try_into().expect("4 bytes"));
    let hash_at = |o: usize| -> [u8; 32] { bytes[o..o + 32].try_into().expect("32 bytes") };
    if bytes[..8] != CACHE_MAGIC {
        return Err(err(Problem::NotCache { what: format!("magic bytes {:02x?}", &bytes[..8]) }));
    }
    let version = u32_at(8);
    if version != CACHE_VERSION {
        return Err(err(Problem::NotCache {
            what: format!("irradiance-cache format version {version}, this build reads version {CACHE_VERSION}"),
        }));
    }
    let header_len = u32_at(12) as usize;
    if !header_len_ok(header_len, FIXED_LEN, len) {
        return Err(err(Problem::Field { field: "header_len", value: header_len as u64 }));
    }
    if !check_ok(&bytes, header_len) {
        return Err(err(Problem::HeaderChecksum));
    }
    let record_size = u32_at(16) as usize;
    if record_size != size_of::<CacheRecord>() {
        return Err(err(Problem::Field { field: "record_size", value: record_size as u64 }));
    }
    let (width, height) = (u32_at(20), u32_at(24));
    let n = u64::from_le_bytes(bytes[32..40].try_into().expect("8 bytes"));
    let params = params_text(&bytes, FIXED_LEN, u32_at(136) as usize, header_len).map_err(err)?;
    let expected = n.checked_mul(record_size as u64).and_then(|p| p.checked_add(header_len as u64));
    if expected != Some(len) {
        return Err(err(Problem::NotCache {
            what: format!(
                "truncated or padded: {len} bytes, header says {} ({n} records of {record_size} bytes)",
                expected.unwrap_or(u64::MAX)
            ),
        }));
    }
    let payload = &bytes[header_len..];
    if blake3::hash(payload).as_bytes() != &hash_at(104) {
        return Err(err(Problem::PayloadChecksum));
    }
    let records: Vec<CacheRecord> = payload.chunks_exact(record_size).map(bytemuck::pod_read_unaligned).collect();
    for (i, r) in records.iter().enumerate() {
        let finite = r.p.iter().chain(&r.n).chain(&r.e).chain(&r.grad_t).chain(&r.grad_r).all(|v| v.is_finite());
        if !finite || !(r.r > 0.0) || !r.r.is_finite() || r.e.iter().any(|&e| e < 0.0) {
            return Err(err(Problem::NotCache {
                what: format!("record {i} holds a non-finite value, a negative irradiance or a radius <= 0"),
            }));
        }
    }
    Ok(CacheFile { width, height, scene_hash: hash_at(40), map_hash: hash_at(72), params, records })
}
