//! The file header: every field, its offset and its meaning, in one place.
//!
//! ```text
//! offset size field
//!      0    8 magic            b"PHOTMAP\x1a"
//!      8    4 version          u32, must be 3
//!     12    4 header_len       u32: bytes before the first record; multiple of 16
//!     16    1 kind             1 = global, 2 = caustic
//!     17    1 order            0 = unsorted, 1 = left-balanced kd-tree in heap order,
//!                              2 = one slice of a trace (power not yet divided by
//!                              the emitted count, n_emitted 0; only
//!                              `photon-trace merge` reads it)
//!     18    1 layout           1 = compact 18 B, 2 = compact+irradiance 23 B,
//!                              3 = full 40 B, 4 = full+irradiance 64 B
//!     19    1 flags            bit 0: irradiance has been precomputed; other bits 0
//!     20    4 record_size      u32, must match the layout
//!     24    8 n_photons        u64
//!     32    8 n_emitted        u64: photons emitted to fill this map (power scale)
//!     40   12 bounds_min       f32 x 3 [m]
//!     52   12 bounds_max       f32 x 3 [m]
//!     64   24 total_power      f64 x 3 [W]: sum of the decoded record powers
//!     88   32 scene_hash       blake3 of the scene file and its buffers
//!    120   32 payload_hash     blake3 of the record bytes
//!    152    4 scene_diagonal   f32 [m]: the scene's bounding-box diagonal, the one
//!                              reference of every relative radius (stages 3 and 4)
//!    156   24 origin           f64 x 3 [m]: world position of the map's coordinate
//!                              origin (scenes are stored relative to their camera;
//!                              add this for world coordinates)
//!    180    4 params_len       u32
//!    184    n params           UTF-8 (JSON) of the parameters that produced the map
//!      .    . zero padding
//! len-8    8 header_check     first 8 bytes of blake3(header bytes before this field)
//! ```
//! All integers and floats are little-endian.

use crate::flags;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

/// File signature.
pub const MAGIC: [u8; 8] = *b"PHOTMAP\x1a";
/// The only version this build reads and writes.
pub const VERSION: u32 = 3;
const FIXED_LEN: usize = 184;
const MAX_PARAMS: usize = 1 << 20;

/// Which photon map a file holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum MapKind {
    /// All photons at non-specular hits (Jensen's global map).
    Global = 1,
    /// Photons that reached a non-specular surface through specular bounces only.
    Caustic = 2,
    /// Photons at scattering events inside participating media (Jensen and
    /// Christensen 1998), each flagged `flags::VOLUME`.
    Volume = 3,
}

/// The order of the records.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Order {
    /// As traced.
    Unsorted = 0,
    /// Left-balanced kd-tree in heap order (Christensen 1999 section 1.2).
    KdTree = 1,
    /// One slice of a trace, as traced: record power is Phi-hat / p_select [W per
    /// channel], not yet divided by the emitted count (which only the merge of all
    /// slices knows; `n_emitted` is 0). Read only when asked for by
    /// `ReadExpect::order`, so no stage mistakes it for a map.
    Slice = 2,
}

/// The record layout.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Layout {
    /// 18-byte [`crate::CompactPhoton`].
    Compact = 1,
    /// 23-byte [`crate::CompactIrrPhoton`].
    CompactIrradiance = 2,
    /// 40-byte [`crate::FullPhoton`].
    Full = 3,
    /// 64-byte [`crate::FullIrrPhoton`].
    FullIrradiance = 4,
}

impl Layout {
    /// Bytes per record.
    pub fn record_size(self) -> usize {
        match self {
            Layout::Compact => 18,
            Layout::CompactIrradiance => 23,
            Layout::Full => 40,
            Layout::FullIrradiance => 64,
        }
    }
    /// True for the layouts with a surface normal and irradiance.
    pub fn has_normal(self) -> bool {
        matches!(self, Layout::CompactIrradiance | Layout::FullIrradiance)
    }
    /// The name used on command lines and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Layout::Compact => "compact",
            Layout::CompactIrradiance => "compact+irradiance",
            Layout::Full => "full",
            Layout::FullIrradiance => "full+irradiance",
        }
    }
}

/// Everything in a header except the checks.
#[derive(Clone, Debug, PartialEq)]
pub struct Header {
    /// Global or caustic.
    pub kind: MapKind,
    /// Unsorted or kd-tree.
    pub order: Order,
    /// Record layout.
    pub layout: Layout,
    /// Irradiance has been precomputed (stage 3).
    pub has_irradiance: bool,
    /// Number of records.
    pub n_photons: u64,
    /// Photons emitted to fill this map.
    pub n_emitted: u64,
    /// Bounds of the photon positions \[m\] (zero for an empty map).
    pub bounds_min: [f32; 3],
    /// Bounds of the photon positions \[m\].
    pub bounds_max: [f32; 3],
    /// Sum of the record powers [W per channel].
    pub total_power: [f64; 3],
    /// blake3 of the scene the map was traced in.
    pub scene_hash: [u8; 32],
    /// blake3 of the record bytes.
    pub payload_hash: [u8; 32],
    /// The scene's bounding-box diagonal \[m\]: relative radii (`max_radius_rel_diag`)
    /// mean this length times the fraction in every stage.
    pub scene_diagonal: f32,
    /// World position \[m\] of the coordinate origin of the positions (the scene's
    /// camera, `Scene::origin`): world = position + origin.
    pub origin: [f64; 3],
    /// Parameters that produced the map (JSON text).
    pub params: String,
}

impl Header {
    /// A header for a new map; derived fields are filled when the map is written.
    pub fn new(
        kind: MapKind,
        order: Order,
        layout: Layout,
        n_emitted: u64,
        scene_hash: [u8; 32],
        scene_diagonal: f32,
        params: String,
    ) -> Header {
        Header {
            kind,
            order,
            layout,
            has_irradiance: false,
            n_photons: 0,
            n_emitted,
            bounds_min: [0.0; 3],
            bounds_max: [0.0; 3],
            total_power: [0.0; 3],
            scene_hash,
            payload_hash: [0; 32],
            scene_diagonal,
            origin: [0.0; 3],
            params,
        }
    }

    /// The header with positions relative to world position `origin` \[m\].
    pub fn with_origin(self, origin: [f64; 3]) -> Header {
        Header { origin, ..self }
    }
}

/// What the reader of a file requires of it. `None` accepts anything.
#[derive(Clone, Debug, Default)]
pub struct ReadExpect {
    /// Required map kind.
    pub kind: Option<MapKind>,
    /// Required order.
    pub order: Option<Order>,
    /// Require precomputed irradiance.
    pub irradiance: Option<bool>,
    /// Required scene hash (maps from another scene are refused).
    pub scene_hash: Option<[u8; 32]>,
}

/// A photon-map file that cannot be used; displays as one line naming the file.
#[derive(Debug, thiserror::Error)]
#[error("{}: {problem}", path.display())]
pub struct FormatError {
    /// The file.
    pub path: PathBuf,
    /// What is wrong.
    pub problem: Problem,
}

/// What is wrong with a photon-map file.
#[derive(Debug, thiserror::Error)]
pub enum Problem {
    /// Reading or writing failed.
    #[error("{0}")]
    Io(std::io::Error),
    /// Shorter than a header.
    #[error("not a photon map: only {len} bytes")]
    TooShort {
        /// File length.
        len: u64,
    },
    /// Wrong signature.
    #[error("not a photon map: magic bytes {found:02x?}, expected {MAGIC:02x?}")]
    Magic {
        /// What the file starts with.
        found: [u8; 8],
    },
    /// Another format version.
    #[error("photon-map format version {found}, this build reads version {VERSION}")]
    Version {
        /// The file's version.
        found: u32,
    },
    /// Header checksum mismatch.
    #[error("header is corrupted (checksum mismatch)")]
    HeaderChecksum,
    /// A header field out of range.
    #[error("header field {field} has invalid value {value}")]
    Field {
        /// Field name.
        field: &'static str,
        /// Its value.
        value: u64,
    },
    /// The file is not as long as the header says.
    #[error("truncated or padded: {actual} bytes, header says {expected} ({n_photons} photons of {record_size} bytes)")]
    Length {
        /// Expected file length.
        expected: u64,
        /// Actual file length.
        actual: u64,
        /// Photon count in the header.
        n_photons: u64,
        /// Record size.
        record_size: usize,
    },
    /// Payload checksum mismatch.
    #[error("photon records are corrupted (checksum mismatch)")]
    PayloadChecksum,
    /// A record holds an impossible value.
    #[error("photon {index} is invalid: {what}")]
    Record {
        /// Record index.
        index: u64,
        /// The problem.
        what: &'static str,
    },
    /// Not the map the reader wanted.
    #[error("expected {expected}, found {found}")]
    Wrong {
        /// What the reader wanted.
        expected: String,
        /// What the file is.
        found: String,
    },
    /// An irradiance-cache or progressive-state file that cannot be used (see
    /// [`crate::framed`]).
    #[error("not a usable {kind}: {what}")]
    Unusable {
        /// What the file should have been ("irradiance cache").
        kind: &'static str,
        /// What is wrong.
        what: String,
    },
    /// Made from another scene.
    #[error("made from another scene (scene hash {found} differs from {expected})")]
    OtherScene {
        /// The reader's scene hash (short hex).
        expected: String,
        /// The file's scene hash (short hex).
        found: String,
    },
}

fn fail(path: &Path, problem: Problem) -> FormatError {
    FormatError { path: path.to_owned(), problem }
}

fn short_hex(h: &[u8; 32]) -> String {
    h[..6].iter().map(|b| format!("{b:02x}")).collect()
}

/// Serialise a header for a payload of `payload_len` bytes.
pub fn encode(h: &Header) -> Vec<u8> {
    let params = h.params.as_bytes();
    let header_len = framed_len(FIXED_LEN, params.len());
    let mut b = Vec::with_capacity(header_len);
    b.extend_from_slice(&MAGIC);
    b.extend_from_slice(&VERSION.to_le_bytes());
    b.extend_from_slice(&(header_len as u32).to_le_bytes());
    b.extend_from_slice(&[h.kind as u8, h.order as u8, h.layout as u8, h.has_irradiance as u8]);
    b.extend_from_slice(&(h.layout.record_size() as u32).to_le_bytes());
    b.extend_from_slice(&h.n_photons.to_le_bytes());
    b.extend_from_slice(&h.n_emitted.to_le_bytes());
    for v in h.bounds_min.iter().chain(&h.bounds_max) {
        b.extend_from_slice(&v.to_le_bytes());
    }
    for v in &h.total_power {
        b.extend_from_slice(&v.to_le_bytes());
    }
    b.extend_from_slice(&h.scene_hash);
    b.extend_from_slice(&h.payload_hash);
    b.extend_from_slice(&h.scene_diagonal.to_le_bytes());
    for v in &h.origin {
        b.extend_from_slice(&v.to_le_bytes());
    }
    b.extend_from_slice(&(params.len() as u32).to_le_bytes());
    debug_assert_eq!(b.len(), FIXED_LEN);
    seal(&mut b, params, header_len);
    b
}

/// The length of a header whose fixed part is `fixed_len` bytes and whose
/// parameter text is `params_len` bytes: padded, with an 8-byte check, to a
/// multiple of 16 (both file formats of this crate frame their headers so).
pub(crate) fn framed_len(fixed_len: usize, params_len: usize) -> usize {
    (fixed_len + params_len + 8).div_ceil(16) * 16
}

/// Finish a header whose fixed part is in `b`: the parameter text, zero padding
/// and the check (the first 8 bytes of blake3 over everything before it).
pub(crate) fn seal(b: &mut Vec<u8>, params: &[u8], header_len: usize) {
    b.extend_from_slice(params);
    b.resize(header_len - 8, 0);
    let check = blake3::hash(b);
    b.extend_from_slice(&check.as_bytes()[..8]);
}

/// True when `header_len` can frame a header of fixed part `fixed_len` in a file
/// of `file_len` bytes.
pub(crate) fn header_len_ok(header_len: usize, fixed_len: usize, file_len: u64) -> bool {
    header_len >= fixed_len + 8
        && header_len.is_multiple_of(16)
        && header_len <= fixed_len + MAX_PARAMS + 24
        && header_len as u64 <= file_len
}

/// True when the header's check matches its bytes.
pub(crate) fn check_ok(bytes: &[u8], header_len: usize) -> bool {
    blake3::hash(&bytes[..header_len - 8]).as_bytes()[..8] == bytes[header_len - 8..header_len]
}

/// The parameter text after a fixed part of `fixed_len` bytes.
pub(crate) fn params_text(
    bytes: &[u8],
    fixed_len: usize,
    params_len: usize,
    header_len: usize,
) -> Result<String, Problem> {
    if fixed_len + params_len + 8 > header_len {
        return Err(Problem::Field { field: "params_len", value: params_len as u64 });
    }
    std::str::from_utf8(&bytes[fixed_len..fixed_len + params_len])
        .map(str::to_owned)
        .map_err(|_| Problem::Field { field: "params (not UTF-8)", value: params_len as u64 })
}

pub(crate) fn write_file(path: &Path, h: &Header, payload: &[u8]) -> Result<(), FormatError> {
    let head = encode(h);
    crate::write_atomically(path, |w| {
        w.write_all(&head)?;
        w.write_all(payload)
    })
    .map_err(|e| fail(path, Problem::Io(e)))
}

struct Cursor<'a>(&'a [u8]);
impl Cursor<'_> {
    fn take<const N: usize>(&mut self) -> [u8; N] {
        let (a, rest) = self.0.split_at(N);
        self.0 = rest;
        a.try_into().expect("split_at gave N bytes")
    }
    fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.take())
    }
    fn u64(&mut self) -> u64 {
        u64::from_le_bytes(self.take())
    }
    fn f32(&mut self) -> f32 {
        f32::from_le_bytes(self.take())
    }
    fn f64(&mut self) -> f64 {
        f64::from_le_bytes(self.take())
    }
}

/// Parse and check a header from the first bytes of a file of `file_len` bytes.
/// Returns the header and its length.
fn decode(path: &Path, bytes: &[u8], file_len: u64) -> Result<(Header, usize), FormatError> {
    let err = |p| fail(path, p);
    if bytes.len() < FIXED_LEN + 8 {
        return Err(err(Problem::TooShort { len: file_len }));
    }
    let mut c = Cursor(bytes);
    let magic: [u8; 8] = c.take();
    if magic != MAGIC {
        return Err(err(Problem::Magic { found: magic }));
    }
    let version = c.u32();
    if version != VERSION {
        return Err(err(Problem::Version { found: version }));
    }
    let header_len = c.u32() as usize;
    if !header_len_ok(header_len, FIXED_LEN, file_len) {
        return Err(err(Problem::Field { field: "header_len", value: header_len as u64 }));
    }
    if bytes.len() < header_len {
        return Err(err(Problem::TooShort { len: file_len }));
    }
    if !check_ok(bytes, header_len) {
        return Err(err(Problem::HeaderChecksum));
    }
    let [kind, order, layout, hflags] = c.take();
    let kind = match kind {
        1 => MapKind::Global,
        2 => MapKind::Caustic,
        3 => MapKind::Volume,
        v => return Err(err(Problem::Field { field: "kind", value: v as u64 })),
    };
    let order = match order {
        0 => Order::Unsorted,
        1 => Order::KdTree,
        2 => Order::Slice,
        v => return Err(err(Problem::Field { field: "order", value: v as u64 })),
    };
    let layout = match layout {
        1 => Layout::Compact,
        2 => Layout::CompactIrradiance,
        3 => Layout::Full,
        4 => Layout::FullIrradiance,
        v => return Err(err(Problem::Field { field: "layout", value: v as u64 })),
    };
    if hflags > 1 || (hflags == 1 && !layout.has_normal()) {
        return Err(err(Problem::Field { field: "flags", value: hflags as u64 }));
    }
    let record_size = c.u32();
    if record_size as usize != layout.record_size() {
        return Err(err(Problem::Field { field: "record_size", value: record_size as u64 }));
    }
    let n_photons = c.u64();
    let n_emitted = c.u64();
    let mut bounds = [0f32; 6];
    for v in &mut bounds {
        *v = c.f32();
    }
    let total_power = [c.f64(), c.f64(), c.f64()];
    let scene_hash: [u8; 32] = c.take();
    let payload_hash: [u8; 32] = c.take();
    let scene_diagonal = c.f32();
    if !(scene_diagonal > 0.0) || !scene_diagonal.is_finite() {
        return Err(err(Problem::Field { field: "scene_diagonal (not finite and positive)", value: 0 }));
    }
    let origin = [c.f64(), c.f64(), c.f64()];
    if !origin.iter().all(|v| v.is_finite()) {
        return Err(err(Problem::Field { field: "origin (not finite)", value: 0 }));
    }
    let params = params_text(bytes, FIXED_LEN, c.u32() as usize, header_len).map_err(err)?;
    let expected = n_photons.checked_mul(record_size as u64).and_then(|p| p.checked_add(header_len as u64));
    if expected != Some(file_len) {
        return Err(err(Problem::Length {
            expected: expected.unwrap_or(u64::MAX),
            actual: file_len,
            n_photons,
            record_size: record_size as usize,
        }));
    }
    if !bounds.iter().all(|v| v.is_finite()) || !total_power.iter().all(|v| v.is_finite()) {
        return Err(err(Problem::Field { field: "bounds/total_power (not finite)", value: 0 }));
    }
    let header = Header {
        kind,
        order,
        layout,
        has_irradiance: hflags == 1,
        n_photons,
        n_emitted,
        bounds_min: [bounds[0], bounds[1], bounds[2]],
        bounds_max: [bounds[3], bounds[4], bounds[5]],
        total_power,
        scene_hash,
        payload_hash,
        scene_diagonal,
        origin,
        params,
    };
    Ok((header, header_len))
}

fn check_expectations(path: &Path, h: &Header, expect: &ReadExpect) -> Result<(), FormatError> {
    let wrong = |expected: String, found: String| Err(fail(path, Problem::Wrong { expected, found }));
    if let Some(k) = expect.kind
        && k != h.kind
    {
        return wrong(format!("a {k:?} photon map"), format!("a {:?} photon map", h.kind));
    }
    let name = |o: Order| match o {
        Order::KdTree => "a kd-tree (run photon-sort first)",
        Order::Unsorted => "an unsorted map",
        Order::Slice => "a trace slice (run photon-trace merge first)",
    };
    if let Some(o) = expect.order
        && o != h.order
    {
        return wrong(name(o).into(), name(h.order).trim_end_matches(" (run photon-sort first)").into());
    }
    if h.order == Order::Slice && expect.order.is_none() {
        return wrong("a photon map".into(), name(h.order).into());
    }
    if let Some(i) = expect.irradiance
        && i != h.has_irradiance
    {
        let name = |i: bool| {
            if i {
                "a map with precomputed irradiance (run photon-irradiance first)"
            } else {
                "a map without precomputed irradiance"
            }
        };
        return wrong(
            name(i).into(),
            if h.has_irradiance { "one with irradiance".into() } else { "one without irradiance".into() },
        );
    }
    if let Some(s) = expect.scene_hash
        && s != h.scene_hash
    {
        return Err(fail(path, Problem::OtherScene { expected: short_hex(&s), found: short_hex(&h.scene_hash) }));
    }
    Ok(())
}

pub(crate) fn read_file(path: &Path, expect: &ReadExpect) -> Result<crate::AnyMap, FormatError> {
    use crate::{AnyMap, CompactIrrPhoton, CompactPhoton, FullIrrPhoton, FullPhoton, PhotonMap};
    let io = |e| fail(path, Problem::Io(e));
    let mut file = std::fs::File::open(path).map_err(io)?;
    let file_len = file.metadata().map_err(io)?.len();
    // Read the fixed part, then the rest of the header.
    let mut head = vec![0u8; (FIXED_LEN + 8).min(file_len as usize)];
    file.read_exact(&mut head).map_err(io)?;
    if head.len() >= 16 && head[..8] == MAGIC && u32::from_le_bytes(head[8..12].try_into().unwrap()) == VERSION {
        let header_len = u32::from_le_bytes(head[12..16].try_into().unwrap()) as usize;
        if header_len > head.len() && header_len as u64 <= file_len && header_len <= FIXED_LEN + MAX_PARAMS + 24 {
            let old = head.len();
            head.resize(header_len, 0);
            file.read_exact(&mut head[old..]).map_err(io)?;
        }
    }
    let (header, _) = decode(path, &head, file_len)?;
    check_expectations(path, &header, expect)?;
    fn load<R: crate::PhotonRecord>(
        path: &Path,
        file: &mut std::fs::File,
        header: Header,
    ) -> Result<PhotonMap<R>, FormatError> {
        let n = header.n_photons as usize;
        let mut records: Vec<R> = Vec::new();
        records
            .try_reserve_exact(n)
            .map_err(|_| fail(path, Problem::Field { field: "n_photons (does not fit in memory)", value: n as u64 }))?;
        records.resize(n, R::zeroed());
        file.read_exact(bytemuck::cast_slice_mut(&mut records)).map_err(|e| fail(path, Problem::Io(e)))?;
        if blake3::hash(bytemuck::cast_slice(&records)).as_bytes() != &header.payload_hash {
            return Err(fail(path, Problem::PayloadChecksum));
        }
        for (i, r) in records.iter().enumerate() {
            let bad = |what| Err(fail(path, Problem::Record { index: i as u64, what }));
            if !r.position().is_finite() {
                return bad("position is not finite");
            }
            if !pm_color::is_valid(r.power()) {
                return bad("power is negative or not finite");
            }
            // Every bit of the flags byte has a meaning (`flags::KNOWN` is all
            // of them), so no flag value is invalid.
            const _: () = assert!(flags::KNOWN == u8::MAX);
            if !pm_color::is_valid(r.irradiance()) {
                return bad("irradiance is negative or not finite");
            }
        }
        Ok(PhotonMap { header, records })
    }
    Ok(match header.layout {
        Layout::Compact => AnyMap::Compact(load::<CompactPhoton>(path, &mut file, header)?),
        Layout::CompactIrradiance => AnyMap::CompactIrr(load::<CompactIrrPhoton>(path, &mut file, header)?),
        Layout::Full => AnyMap::Full(load::<FullPhoton>(path, &mut file, header)?),
        Layout::FullIrradiance => AnyMap::FullIrr(load::<FullIrrPhoton>(path, &mut file, header)?),
    })
}
