//! The four record layouts and the decoded photon.

use crate::direction::{decode_direction, encode_direction};
use crate::header::Layout;
use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use pm_color::{Rgb, Rgbe};

/// Bits of a photon's flags byte.
pub mod flags {
    /// The kd-tree split axis of this node (0 = x, 1 = y, 2 = z); [`AXIS_LEAF`] for leaves
    /// and unsorted maps.
    pub const AXIS_MASK: u8 = 0b11;
    /// Value of the axis bits for a node without a split.
    pub const AXIS_LEAF: u8 = 0b11;
    /// First non-specular hit after leaving the light (direct illumination).
    pub const DIRECT: u8 = 1 << 2;
    /// Arrived through one or more specular bounces only (light-specular+-diffuse path).
    pub const CAUSTIC: u8 = 1 << 3;
    /// Ignored by every query (a tombstone, e.g. for ring buffers of the real-time mode).
    pub const UNUSED: u8 = 1 << 4;
    /// Carries a precomputed irradiance (Christensen 1999 section 2.1).
    pub const HAS_IRRADIANCE: u8 = 1 << 5;
    /// Stored at a scattering event inside a participating medium, not on a surface
    /// (a volume map's photon, Jensen and Christensen 1998): its `wi` is the
    /// direction it arrived from, its normal zero. With [`DIRECT`], the first event
    /// of a path straight from the light; with [`CAUSTIC`], after specular bounces
    /// only (L S+ V).
    pub const VOLUME: u8 = 1 << 6;
    /// Lies under a cover: another surface faces it from closer than the cover
    /// distance the irradiance precompute was given (a light's panel millimetres
    /// below the ceiling, an object a millimetre from a wall). The light in such a
    /// gap is the gap's own (bright with light trapped over a two-sided panel, dark
    /// behind an object), not the open surface's around it, so estimates and
    /// lookups keep covered and open photons apart. Set by the precompute.
    pub const COVERED: u8 = 1 << 7;
    /// Every bit with a meaning; the rest must be zero in a valid file.
    pub const KNOWN: u8 = AXIS_MASK | DIRECT | CAUSTIC | UNUSED | HAS_IRRADIANCE | VOLUME | COVERED;
}

/// A photon with every field decoded.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Photon {
    /// Position \[m\].
    pub position: Vec3,
    /// Power Phi_p [W per channel].
    pub power: Rgb,
    /// Unit direction toward where the photon came from (pointing away from the surface).
    pub wi: Vec3,
    /// Flags (see [`flags`]).
    pub flags: u8,
    /// Unit geometric normal of the surface the photon is stored on (zero when the
    /// layout does not carry one).
    pub normal: Vec3,
    /// Precomputed irradiance E [W m^-2 per channel] (zero when not computed).
    pub irradiance: Rgb,
}

/// A fixed-size photon record as stored in files and in memory. Layout-generic code
/// (kd-tree, estimates) works on any implementor.
pub trait PhotonRecord: Pod + Send + Sync + std::fmt::Debug + 'static {
    /// The layout tag written in file headers.
    const LAYOUT: Layout;
    /// Encode a photon (lossy for compact layouts).
    fn encode(p: &Photon) -> Self;
    /// Decode every field.
    fn decode(&self) -> Photon {
        Photon {
            position: self.position(),
            power: self.power(),
            wi: self.wi(),
            flags: self.flags(),
            normal: self.normal(),
            irradiance: self.irradiance(),
        }
    }
    /// Position \[m\] (exact in every layout).
    fn position(&self) -> Vec3;
    /// Flags byte.
    fn flags(&self) -> u8;
    /// Replace the flags byte.
    fn set_flags(&mut self, f: u8);
    /// Power [W per channel].
    fn power(&self) -> Rgb;
    /// Unit incident direction (toward the light).
    fn wi(&self) -> Vec3;
    /// Unit surface normal, or zero when the layout has none.
    fn normal(&self) -> Vec3;
    /// Precomputed irradiance [W m^-2 per channel] (zero in layouts without it).
    fn irradiance(&self) -> Rgb;
    /// Store a precomputed irradiance (ignored by layouts without it).
    fn set_irradiance(&mut self, e: Rgb);
}

/// Christensen's 18-byte photon.
#[repr(C, packed)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct CompactPhoton {
    /// Position \[m\], f32 x 3.
    pub pos: [f32; 3],
    /// RGBE power.
    pub power: [u8; 4],
    /// Octahedral byte of the incident direction.
    pub dir: u8,
    /// Flags.
    pub flags: u8,
}

/// The 23-byte photon with precomputed irradiance and surface normal.
#[repr(C, packed)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct CompactIrrPhoton {
    /// Position \[m\], f32 x 3.
    pub pos: [f32; 3],
    /// RGBE power.
    pub power: [u8; 4],
    /// Octahedral byte of the incident direction.
    pub dir: u8,
    /// Flags.
    pub flags: u8,
    /// RGBE irradiance.
    pub irradiance: [u8; 4],
    /// Octahedral byte of the surface normal.
    pub normal: u8,
}

/// Full-precision photon (40 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct FullPhoton {
    /// Position \[m\].
    pub pos: [f32; 3],
    /// Power [W per channel].
    pub power: [f32; 3],
    /// Unit incident direction.
    pub dir: [f32; 3],
    /// Flags in the low byte; the rest zero.
    pub flags: u32,
}

/// Full-precision photon with irradiance and normal (64 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct FullIrrPhoton {
    /// Position \[m\].
    pub pos: [f32; 3],
    /// Power [W per channel].
    pub power: [f32; 3],
    /// Unit incident direction.
    pub dir: [f32; 3],
    /// Flags in the low byte; the rest zero.
    pub flags: u32,
    /// Irradiance [W m^-2 per channel].
    pub irradiance: [f32; 3],
    /// Unit surface normal.
    pub normal: [f32; 3],
}

const _: () = assert!(std::mem::size_of::<CompactPhoton>() == 18);
const _: () = assert!(std::mem::size_of::<CompactIrrPhoton>() == 23);
const _: () = assert!(std::mem::size_of::<FullPhoton>() == 40);
const _: () = assert!(std::mem::size_of::<FullIrrPhoton>() == 64);

/// Position, flags, power and incident direction of the compact records (RGBE power,
/// octahedral direction byte).
macro_rules! compact_accessors {
    () => {
        #[inline]
        fn position(&self) -> Vec3 {
            Vec3::from_array(self.pos)
        }
        #[inline]
        fn flags(&self) -> u8 {
            self.flags
        }
        #[inline]
        fn set_flags(&mut self, f: u8) {
            self.flags = f;
        }
        #[inline]
        fn power(&self) -> Rgb {
            Rgbe(self.power).decode()
        }
        #[inline]
        fn wi(&self) -> Vec3 {
            decode_direction(self.dir)
        }
    };
}

/// Position, flags, power and incident direction of the full-precision records.
macro_rules! full_accessors {
    () => {
        #[inline]
        fn position(&self) -> Vec3 {
            Vec3::from_array(self.pos)
        }
        #[inline]
        fn flags(&self) -> u8 {
            self.flags as u8
        }
        #[inline]
        fn set_flags(&mut self, f: u8) {
            self.flags = f as u32;
        }
        #[inline]
        fn power(&self) -> Rgb {
            Rgb::from_array(self.power)
        }
        #[inline]
        fn wi(&self) -> Vec3 {
            Vec3::from_array(self.dir)
        }
    };
}

impl PhotonRecord for CompactPhoton {
    const LAYOUT: Layout = Layout::Compact;
    fn encode(p: &Photon) -> Self {
        CompactPhoton {
            pos: p.position.to_array(),
            power: Rgbe::encode(p.power).0,
            dir: encode_direction(p.wi),
            flags: p.flags,
        }
    }
    compact_accessors!();
    fn normal(&self) -> Vec3 {
        Vec3::ZERO
    }
    fn irradiance(&self) -> Rgb {
        Rgb::ZERO
    }
    fn set_irradiance(&mut self, _: Rgb) {}
}

impl PhotonRecord for CompactIrrPhoton {
    const LAYOUT: Layout = Layout::CompactIrradiance;
    fn encode(p: &Photon) -> Self {
        CompactIrrPhoton {
            pos: p.position.to_array(),
            power: Rgbe::encode(p.power).0,
            dir: encode_direction(p.wi),
            flags: p.flags,
            irradiance: Rgbe::encode(p.irradiance).0,
            normal: encode_direction(p.normal),
        }
    }
    compact_accessors!();
    #[inline]
    fn normal(&self) -> Vec3 {
        decode_direction(self.normal)
    }
    #[inline]
    fn irradiance(&self) -> Rgb {
        Rgbe(self.irradiance).decode()
    }
    fn set_irradiance(&mut self, e: Rgb) {
        self.irradiance = Rgbe::encode(e).0;
    }
}

impl PhotonRecord for FullPhoton {
    const LAYOUT: Layout = Layout::Full;
    fn encode(p: &Photon) -> Self {
        FullPhoton {
            pos: p.position.to_array(),
            power: p.power.to_array(),
            dir: p.wi.to_array(),
            flags: p.flags as u32,
        }
    }
    full_accessors!();
    fn normal(&self) -> Vec3 {
        Vec3::ZERO
    }
    fn irradiance(&self) -> Rgb {
        Rgb::ZERO
    }
    fn set_irradiance(&mut self, _: Rgb) {}
}

impl PhotonRecord for FullIrrPhoton {
    const LAYOUT: Layout = Layout::FullIrradiance;
    fn encode(p: &Photon) -> Self {
        FullIrrPhoton {
            pos: p.position.to_array(),
            power: p.power.to_array(),
            dir: p.wi.to_array(),
            flags: p.flags as u32,
            irradiance: p.irradiance.to_array(),
            normal: p.normal.to_array(),
        }
    }
    full_accessors!();
    #[inline]
    fn normal(&self) -> Vec3 {
        Vec3::from_array(self.normal)
    }
    #[inline]
    fn irradiance(&self) -> Rgb {
        Rgb::from_array(self.irradiance)
    }
    fn set_irradiance(&mut self, e: Rgb) {
        self.irradiance = e.to_array();
    }
}
