//! The frame that this crate's record files other than photon maps share (the
//! irradiance cache, [`crate::icache`], and the progressive state,
//! [`crate::sppm`], [`crate::passes`]): a fixed header, a parameter text, a check, then a flat array
//! of fixed-size records.
//!
//! ```text
//! offset size field
//!      0    8 magic            the file kind's signature
//!      8    4 version          u32, the kind's one version
//!     12    4 header_len       u32: bytes before the first record; multiple of 16
//!     16    4 record_size      u32, the kind's record size
//!     20    4 width            u32: the image the records cover [pixels]
//!     24    4 height           u32 [pixels]
//!     28    4 count            u32: the kind's (irradiance cache: zero; state: passes)
//!     32    8 n_records        u64
//!     40   32 scene_hash       blake3 of the scene file and its buffers
//!     72   32 source_hash      the kind's (irradiance cache: the global map's
//!                              payload hash; state: zero)
//!    104   32 payload_hash     blake3 of the record bytes
//!    136    4 params_len       u32
//!    140    n params           UTF-8: the settings that shaped the records
//!      .    . zero padding
//! len-8    8 header_check     first 8 bytes of blake3(header bytes before this field)
//! ```
//! All integers and floats are little-endian.

use crate::header::{FormatError, Problem, check_ok, framed_len, header_len_ok, params_text, seal};
use std::io::{Read, Write};
use std::path::Path;

const FIXED_LEN: usize = 140;

/// What distinguishes one kind of framed file from another.
pub(crate) struct Kind {
    /// Its signature.
    pub magic: [u8; 8],
    /// The only version this build reads and writes.
    pub version: u32,
    /// Its record size [bytes].
    pub record_size: usize,
    /// What it is, for messages ("irradiance cache").
    pub name: &'static str,
}

/// The header fields of a framed file other than its frame.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Fields {
    pub width: u32,
    pub height: u32,
    pub count: u32,
    pub scene_hash: [u8; 32],
    pub source_hash: [u8; 32],
    pub params: String,
}

/// The error for a file of `kind` that cannot be used, and why.
pub(crate) fn unusable(path: &Path, kind: &Kind, what: String) -> FormatError {
    FormatError { path: path.to_owned(), problem: Problem::Unusable { kind: kind.name, what } }
}

/// Write `fields` and the records `payload` (a whole number of `kind.record_size`
/// records) to `path` atomically.
pub(crate) fn write(path: &Path, kind: &Kind, f: &Fields, payload: &[u8]) -> Result<(), FormatError> {
    debug_assert!(payload.len().is_multiple_of(kind.record_size));
    let params = f.params.as_bytes();
    let header_len = framed_len(FIXED_LEN, params.len());
    let mut b = Vec::with_capacity(header_len);
    b.extend_from_slice(&kind.magic);
    b.extend_from_slice(&kind.version.to_le_bytes());
    b.extend_from_slice(&(header_len as u32).to_le_bytes());
    b.extend_from_slice(&(kind.record_size as u32).to_le_bytes());
    b.extend_from_slice(&f.width.to_le_bytes());
    b.extend_from_slice(&f.height.to_le_bytes());
    b.extend_from_slice(&f.count.to_le_bytes());
    b.extend_from_slice(&((payload.len() / kind.record_size) as u64).to_le_bytes());
    b.extend_from_slice(&f.scene_hash);
    b.extend_from_slice(&f.source_hash);
    b.extend_from_slice(blake3::hash(payload).as_bytes());
    b.extend_from_slice(&(params.len() as u32).to_le_bytes());
    debug_assert_eq!(b.len(), FIXED_LEN);
    seal(&mut b, params, header_len);
    crate::write_atomically(path, |w| {
        w.write_all(&b)?;
        w.write_all(payload)
    })
    .map_err(|e| FormatError { path: path.to_owned(), problem: Problem::Io(e) })
}

/// Read a framed file of `kind` and check its frame: its fields and the record
/// bytes (a whole number of records whose hash matches).
pub(crate) fn read(path: &Path, kind: &Kind) -> Result<(Fields, Vec<u8>), FormatError> {
    let err = |what: String| unusable(path, kind, what);
    let mut bytes = Vec::new();
    std::fs::File::open(path)
        .and_then(|mut f| f.read_to_end(&mut bytes))
        .map_err(|e| FormatError { path: path.to_owned(), problem: Problem::Io(e) })?;
    let len = bytes.len() as u64;
    if bytes.len() < FIXED_LEN + 8 {
        return Err(err(format!("only {len} bytes")));
    }
    let u32_at = |o: usize| u32::from_le_bytes(bytes[o..o + 4].try_into().expect("4 bytes"));
    let hash_at = |o: usize| -> [u8; 32] { bytes[o..o + 32].try_into().expect("32 bytes") };
    if bytes[..8] != kind.magic {
        return Err(err(format!("magic bytes {:02x?}", &bytes[..8])));
    }
    let version = u32_at(8);
    if version != kind.version {
        return Err(err(format!("{} format version {version}, this build reads version {}", kind.name, kind.version)));
    }
    let field = |field: &'static str, value: u64| FormatError {
        path: path.to_owned(),
        problem: Problem::Field { field, value },
    };
    let header_len = u32_at(12) as usize;
    if !header_len_ok(header_len, FIXED_LEN, len) {
        return Err(field("header_len", header_len as u64));
    }
    if !check_ok(&bytes, header_len) {
        return Err(FormatError { path: path.to_owned(), problem: Problem::HeaderChecksum });
    }
    let record_size = u32_at(16) as usize;
    if record_size != kind.record_size {
        return Err(field("record_size", record_size as u64));
    }
    let n = u64::from_le_bytes(bytes[32..40].try_into().expect("8 bytes"));
    let params = params_text(&bytes, FIXED_LEN, u32_at(136) as usize, header_len)
        .map_err(|problem| FormatError { path: path.to_owned(), problem })?;
    let expected = n.checked_mul(record_size as u64).and_then(|p| p.checked_add(header_len as u64));
    if expected != Some(len) {
        return Err(err(format!(
            "truncated or padded: {len} bytes, header says {} ({n} records of {record_size} bytes)",
            expected.unwrap_or(u64::MAX)
        )));
    }
    if blake3::hash(&bytes[header_len..]).as_bytes() != &hash_at(104) {
        return Err(FormatError { path: path.to_owned(), problem: Problem::PayloadChecksum });
    }
    let fields = Fields {
        width: u32_at(20),
        height: u32_at(24),
        count: u32_at(28),
        scene_hash: hash_at(40),
        source_hash: hash_at(72),
        params,
    };
    bytes.drain(..header_len);
    Ok((fields, bytes))
}

/// The error for a record that holds an impossible value.
pub(crate) fn bad_record(path: &Path, kind: &Kind, index: usize, what: &str) -> FormatError {
    unusable(path, kind, format!("record {index} {what}"))
}

/// A progressive method's state in memory: one record `R` a pixel, row by row,
/// over the passes the records hold ([`crate::sppm`]'s per-pixel SPPM state,
/// [`crate::passes`]' pass sums). Its frame's count is the passes, its source
/// hash zero.
#[derive(Clone, Debug, PartialEq)]
pub struct ImageState<R> {
    /// Image width \[pixels\].
    pub width: u32,
    /// Image height \[pixels\].
    pub height: u32,
    /// Passes accumulated in the records.
    pub passes: u32,
    /// blake3 of the scene.
    pub scene_hash: [u8; 32],
    /// The method and the settings that shaped the state ("name=value" words):
    /// a reader refuses a state made with other settings.
    pub params: String,
    /// One record a pixel, row by row.
    pub records: Vec<R>,
}

/// Write the state `s` as a file of `kind` to `path` atomically.
pub(crate) fn write_state<R: bytemuck::Pod>(path: &Path, kind: &Kind, s: &ImageState<R>) -> Result<(), FormatError> {
    let fields = Fields {
        width: s.width,
        height: s.height,
        count: s.passes,
        scene_hash: s.scene_hash,
        source_hash: [0; 32],
        params: s.params.clone(),
    };
    write(path, kind, &fields, bytemuck::cast_slice(&s.records))
}

/// Read a state file of `kind` and check it: one record a pixel, and no record
/// that `bad` finds something wrong with (it says what).
pub(crate) fn read_state<R: bytemuck::Pod>(
    path: &Path,
    kind: &Kind,
    bad: impl Fn(&R) -> Option<&'static str>,
) -> Result<ImageState<R>, FormatError> {
    let (f, payload) = read(path, kind)?;
    let records: Vec<R> = payload.chunks_exact(kind.record_size).map(bytemuck::pod_read_unaligned).collect();
    if records.len() as u64 != f.width as u64 * f.height as u64 {
        let what = format!("{} records for a {}x{} image", records.len(), f.width, f.height);
        return Err(unusable(path, kind, what));
    }
    if let Some((i, what)) = records.iter().enumerate().find_map(|(i, r)| bad(r).map(|w| (i, w))) {
        return Err(bad_record(path, kind, i, what));
    }
    Ok(ImageState {
        width: f.width,
        height: f.height,
        passes: f.count,
        scene_hash: f.scene_hash,
        params: f.params,
        records,
    })
}
