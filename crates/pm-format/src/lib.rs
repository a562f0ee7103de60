//! The pipeline's binary intermediate files: photon maps (the photon records, the
//! vocabulary every stage shares, and their file), irradiance caches
//! ([`icache`]) and progressive photon mapping's per-pixel state ([`sppm`]). The
//! only code that reads or writes their bytes.
//!
//! A file is a versioned header of our own (explicit little-endian fields, see
//! [`header`]) followed by a flat array of fixed-size records that is read into
//! memory without per-record parsing. Four record layouts exist ([`Layout`]): the
//! paper's compact 18-byte photon (Christensen 1999 section 1.1: 12-byte position,
//! 4-byte RGBE power, 1-byte incident direction, 1-byte flags), its 23-byte
//! extension with precomputed irradiance and surface normal (section 2.1), and
//! full-precision f32 twins of both for accuracy comparisons.
//!
//! Writes are atomic (temporary file, then rename). Every way a file can be wrong
//! gives a [`FormatError`] whose message is one line naming the file.
//!
//! This crate knows nothing about scenes, kd-trees or estimates; in-memory records
//! carry the kd-tree split axis in their flags only because the file is the tree.

#[cfg(target_endian = "big")]
compile_error!("photon-map records are cast from little-endian bytes; big-endian hosts are not supported");

mod atomic;
mod direction;
mod framed;
pub mod header;
pub mod icache;
pub mod passes;
mod record;
pub mod sppm;

pub use atomic::write_atomically;
pub use direction::{DIRECTION_MAX_ERROR_RAD, decode_direction, encode_direction};
pub use framed::ImageState;
pub use header::{FormatError, Header, Layout, MapKind, Order, ReadExpect};
pub use icache::{CacheFile, CacheRecord, read_cache, write_cache};
pub use passes::{PassRecord, PassStateFile, read_pass_state, write_pass_state};
pub use record::{CompactIrrPhoton, CompactPhoton, FullIrrPhoton, FullPhoton, Photon, PhotonRecord, flags};
pub use sppm::{StateFile, StateRecord, read_state, write_state};

use std::path::Path;

/// A photon map in memory: its header and records in file order (for a kd-tree map,
/// heap order: node i has children 2i+1 and 2i+2).
#[derive(Clone, Debug)]
pub struct PhotonMap<R> {
    /// Header as read or to be written (derived fields are refreshed on write).
    pub header: Header,
    /// The records.
    pub records: Vec<R>,
}

/// A photon map of any layout, as read from a file. Use [`with_map!`] to run
/// layout-generic code on it.
#[derive(Clone, Debug)]
pub enum AnyMap {
    /// 18-byte records.
    Compact(PhotonMap<CompactPhoton>),
    /// 23-byte records with irradiance and normal.
    CompactIrr(PhotonMap<CompactIrrPhoton>),
    /// f32 records.
    Full(PhotonMap<FullPhoton>),
    /// f32 records with irradiance and normal.
    FullIrr(PhotonMap<FullIrrPhoton>),
}

/// Run `$body` with `$m` bound to the typed map inside an [`AnyMap`] (by value,
/// reference or mutable reference, following `$any`).
#[macro_export]
macro_rules! with_map {
    ($any:expr, $m:ident => $body:expr) => {
        match $any {
            $crate::AnyMap::Compact($m) => $body,
            $crate::AnyMap::CompactIrr($m) => $body,
            $crate::AnyMap::Full($m) => $body,
            $crate::AnyMap::FullIrr($m) => $body,
        }
    };
}

impl AnyMap {
    /// The header.
    pub fn header(&self) -> &Header {
        with_map!(self, m => &m.header)
    }
    /// Number of photons.
    pub fn len(&self) -> usize {
        with_map!(self, m => m.records.len())
    }
    /// True when the map holds no photons.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Decode every record (for inspection and tests; stages work on records).
    pub fn decode_all(&self) -> Vec<Photon> {
        with_map!(self, m => m.records.iter().map(|r| r.decode()).collect())
    }
}

impl<R: PhotonRecord> PhotonMap<R> {
    /// A map with the given header fields and records; derived header fields (count,
    /// bounds, total power, checksums) are filled in by [`PhotonMap::refresh`].
    pub fn new(mut header: Header, records: Vec<R>) -> Self {
        header.layout = R::LAYOUT;
        let mut map = PhotonMap { header, records };
        map.refresh();
        map
    }

    /// Recompute the header fields derived from the records.
    pub fn refresh(&mut self) {
        self.header.layout = R::LAYOUT;
        self.header.n_photons = self.records.len() as u64;
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        let mut total = [0f64; 3];
        for r in &self.records {
            let p = r.position().to_array();
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
            let phi = r.power();
            for k in 0..3 {
                total[k] += phi[k] as f64;
            }
        }
        if self.records.is_empty() {
            lo = [0.0; 3];
            hi = [0.0; 3];
        }
        self.header.bounds_min = lo;
        self.header.bounds_max = hi;
        self.header.total_power = total;
        self.header.payload_hash = *blake3::hash(bytemuck::cast_slice(&self.records)).as_bytes();
    }

    /// Write atomically to `path` (refreshing derived header fields first).
    pub fn write(&mut self, path: &Path) -> Result<(), FormatError> {
        self.refresh();
        header::write_file(path, &self.header, bytemuck::cast_slice(&self.records))
    }

    /// Convert every record to another layout (through the decoded photon).
    pub fn convert<S: PhotonRecord>(&self) -> PhotonMap<S> {
        let records = self.records.iter().map(|r| S::encode(&r.decode())).collect();
        PhotonMap::new(self.header.clone(), records)
    }
}

/// The first setting in which a file's key `stored` differs from a reader's key
/// `current` (both "name=value" words, as the irradiance cache and progressive
/// state hold them): (the file's word, the reader's word), "(none)" where one
/// key is shorter. None when they are equal.
pub fn key_difference(stored: &str, current: &str) -> Option<(String, String)> {
    let (a, b): (Vec<&str>, Vec<&str>) = (stored.split_whitespace().collect(), current.split_whitespace().collect());
    (0..a.len().max(b.len())).find(|&i| a.get(i) != b.get(i)).map(|i| {
        let word = |v: &[&str]| v.get(i).map_or("(none)".to_string(), |w| w.to_string());
        (word(&a), word(&b))
    })
}

/// Read a photon map, checking it against `expect`.
pub fn read(path: &Path, expect: &ReadExpect) -> Result<AnyMap, FormatError> {
    header::read_file(path, expect)
}

/// Read a photon map and convert it to the record type `R` if it is in another layout.
pub fn read_as<R: PhotonRecord>(path: &Path, expect: &ReadExpect) -> Result<PhotonMap<R>, FormatError> {
    Ok(into_layout(read(path, expect)?))
}

/// Convert any map to the record type `R` (no copy when it already is `R`).
pub fn into_layout<R: PhotonRecord>(any: AnyMap) -> PhotonMap<R> {
    with_map!(any, m => {
        if R::LAYOUT != m.header.layout {
            return m.convert();
        }
        let records = (Box::new(m.records) as Box<dyn std::any::Any>).downcast::<Vec<R>>();
        PhotonMap { header: m.header, records: *records.expect("equal layouts are equal record types") }
    })
}
