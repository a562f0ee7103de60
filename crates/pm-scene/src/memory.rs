//! What a loaded scene holds in memory, buffer by buffer (issue 36: bytes per
//! triangle), summed from the sizes of its buffers rather than measured, so a
//! test can hold it to a budget; the process's peak RSS stays a benchmark figure.

use crate::{LightKind, Scene, Triangle, TriangleExtras};
use std::mem::size_of;

/// Bytes a [`Scene`] holds, by what they are for.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MemoryUse {
    /// The triangles' shading records ([`Triangle`]: positions, normals, material)
    /// and the extras of those that have any (texture coordinates, colours, tangents).
    pub triangles: usize,
    /// The BVH: eight-wide nodes, the triangles' positions in slot order (four to a
    /// SIMD group, padded), and the triangle id of each slot.
    pub bvh: usize,
    /// Which area light each triangle belongs to.
    pub light_of_triangle: usize,
    /// Copies of animated meshes in their nodes' space.
    pub animation: usize,
    /// Texture texels.
    pub textures: usize,
    /// Light sampling tables (area lights' CDFs and bounding spheres).
    pub lights: usize,
    /// The materials (each with its BSDF, factors and texture references) and
    /// their names.
    pub materials: usize,
}

impl MemoryUse {
    /// The sum \[bytes\].
    pub fn total(&self) -> usize {
        self.triangles
            + self.bvh
            + self.light_of_triangle
            + self.animation
            + self.textures
            + self.lights
            + self.materials
    }

    /// The parts that grow with the triangle count, per triangle of `triangles`
    /// \[bytes\] (all but textures and lights).
    pub fn per_triangle(&self, triangles: usize) -> f64 {
        (self.triangles + self.bvh + self.light_of_triangle + self.animation) as f64 / triangles.max(1) as f64
    }
}

impl std::fmt::Display for MemoryUse {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mb = |b: usize| b as f64 / 1e6;
        write!(
            f,
            "{:.1} MB (triangles {:.1}, BVH {:.1}, light ids {:.1}, animation {:.1}, textures {:.1}, lights {:.1}, materials {:.1})",
            mb(self.total()),
            mb(self.triangles),
            mb(self.bvh),
            mb(self.light_of_triangle),
            mb(self.animation),
            mb(self.textures),
            mb(self.lights),
            mb(self.materials)
        )
    }
}

impl Scene {
    /// What this scene's buffers hold (their capacities), by part.
    pub fn memory_use(&self) -> MemoryUse {
        let bytes = |cap: usize, size: usize| cap * size;
        let lights = self
            .lights
            .iter()
            .map(|l| match &l.kind {
                LightKind::Area { cdf, area_per_pick, spheres, .. } => {
                    bytes(cdf.capacity(), 8) + bytes(area_per_pick.capacity(), 4) + bytes(spheres.capacity(), 16)
                }
                LightKind::Environment { env, .. } => env.memory_bytes(),
                _ => 0,
            })
            .sum();
        MemoryUse {
            triangles: bytes(self.triangles.capacity(), size_of::<Triangle>())
                + bytes(self.triangles.iter().filter(|t| t.extras.is_some()).count(), size_of::<TriangleExtras>()),
            bvh: self.bvh.memory_bytes() + self.bvh_tris.memory_bytes(),
            light_of_triangle: bytes(self.light_of_triangle.capacity(), 4),
            animation: self.animation.meshes.iter().map(|m| bytes(m.local.capacity(), size_of::<Triangle>())).sum(),
            textures: self.textures.iter().map(|t| bytes(t.texels.capacity(), 4)).sum(),
            lights,
            materials: bytes(self.materials.capacity(), size_of::<crate::Material>())
                + self.materials.iter().map(|m| m.name.capacity()).sum::<usize>(),
        }
    }
}
