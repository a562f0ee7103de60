//! A static grid of points for fixed-radius queries: cells as large as the query
//! radius over the points' bounding box, the points sorted by cell (counting sort,
//! so cell lists keep point order), no hashing. Built in O(n) each frame by the
//! image-space method's gather, which asks one radius at every mirror and glass
//! pixel: there a hash lookup per cell cost more than the photons it found.

use glam::{IVec3, Vec3};

/// The grid.
#[derive(Clone, Debug)]
pub struct RadiusGrid {
    origin: Vec3,
    cell: f32,
    dims: IVec3,
    /// Points of cell c are `order[start[c]..start[c + 1]]`.
    start: Vec<u32>,
    /// Point ids sorted by cell, each cell's in id order.
    order: Vec<u32>,
    /// Positions in `order`'s order.
    pos: Vec<Vec3>,
}

/// Cells per axis at most (a degenerate radius must not ask for a huge array).
const MAX_DIM: i32 = 512;

impl RadiusGrid {
    /// The grid of `points` for queries of radius up to `radius` \[m\].
    pub fn new(points: &[Vec3], radius: f32) -> RadiusGrid {
        RadiusGrid::with_cells_at_most(points, radius, usize::MAX)
    }

    /// The grid of `points` for queries of radius up to `radius` \[m\] with at
    /// most about `most` cells (larger cells than the radius when the points are
    /// few and the radius small: a grid rebuilt every pass then costs its points,
    /// not its empty cells).
    pub fn with_cells_at_most(points: &[Vec3], radius: f32, most: usize) -> RadiusGrid {
        let (lo, hi) = points
            .iter()
            .filter(|p| p.is_finite())
            .fold((Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)), |(l, h), p| (l.min(*p), h.max(*p)));
        if !(lo.x <= hi.x) {
            return RadiusGrid {
                origin: Vec3::ZERO,
                cell: 1.0,
                dims: IVec3::ONE,
                start: vec![0, 0],
                order: vec![],
                pos: vec![],
            };
        }
        let extent = (hi - lo).max_element();
        let mut cell = radius.max(extent / MAX_DIM as f32).max(f32::MIN_POSITIVE);
        let cells = ((hi - lo) / cell).floor() + Vec3::ONE;
        let n = cells.x as f64 * cells.y as f64 * cells.z as f64;
        if n > most.max(1) as f64 {
            cell *= (n / most.max(1) as f64).cbrt() as f32 * 1.01;
        }
        let dims = (((hi - lo) / cell).floor().as_ivec3() + IVec3::ONE).clamp(IVec3::ONE, IVec3::splat(MAX_DIM));
        let mut g = RadiusGrid { origin: lo, cell, dims, start: Vec::new(), order: Vec::new(), pos: Vec::new() };
        let ncells = (dims.x * dims.y * dims.z) as usize;
        let cell_of: Vec<u32> = points.iter().map(|p| g.index(g.key(*p)).unwrap_or(u32::MAX)).collect();
        let mut count = vec![0u32; ncells + 1];
        for &c in cell_of.iter().filter(|&&c| c != u32::MAX) {
            count[c as usize + 1] += 1;
        }
        for c in 0..ncells {
            count[c + 1] += count[c];
        }
        g.start = count.clone();
        g.order = vec![0; count[ncells] as usize];
        g.pos = vec![Vec3::ZERO; count[ncells] as usize];
        for (i, &c) in cell_of.iter().enumerate() {
            if c != u32::MAX {
                let slot = &mut count[c as usize];
                g.order[*slot as usize] = i as u32;
                g.pos[*slot as usize] = points[i];
                *slot += 1;
            }
        }
        g
    }

    fn key(&self, p: Vec3) -> IVec3 {
        ((p - self.origin) / self.cell).floor().as_ivec3()
    }

    fn index(&self, k: IVec3) -> Option<u32> {
        (k.cmpge(IVec3::ZERO).all() && k.cmplt(self.dims).all())
            .then(|| ((k.z * self.dims.y + k.y) * self.dims.x + k.x) as u32)
    }

    /// Call `f(id, squared distance)` for every point within squared radius `r2`
    /// of `x` (`r2` at most the built radius squared), cell by cell in a fixed
    /// order and by id within a cell.
    pub fn for_each_within(&self, x: Vec3, r2: f32, mut f: impl FnMut(u32, f32)) {
        if !(r2 >= 0.0) {
            return;
        }
        // Only the cells the query's bounding box touches (1 or 2 a side when
        // cells are at least the radius wide, not 3): the cells skipped hold no
        // point within reach, so the points and their order are those of the
        // whole neighbourhood.
        let r = r2.sqrt().min(self.cell * MAX_DIM as f32);
        let lo = self.key(x - Vec3::splat(r)).max(IVec3::ZERO);
        let hi = self.key(x + Vec3::splat(r)).min(self.dims - IVec3::ONE);
        if lo.cmpgt(hi).any() {
            return;
        }
        for z in lo.z..=hi.z {
            for y in lo.y..=hi.y {
                let row = ((z * self.dims.y + y) * self.dims.x) as usize;
                // Cells of one row are consecutive: one range of points.
                let (a, b) = (self.start[row + lo.x as usize], self.start[row + hi.x as usize + 1]);
                for k in a as usize..b as usize {
                    let d2 = self.pos[k].distance_squared(x);
                    if d2 <= r2 {
                        f(self.order[k], d2);
                    }
                }
            }
        }
    }
}
