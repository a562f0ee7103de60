//! A uniform hash grid of photons that can be updated in place: the incremental
//! alternative to rebuilding the kd-tree every frame that Jozwowski 2002 (section
//! 4.4) names as future work. Photons are keyed by a caller's id (a ring-buffer
//! slot); setting an id replaces its photon. Cells are a third of the largest search
//! radius; a k-nearest query visits the cells around the query point nearest first
//! and stops at the first cell farther than the k-th photon found so far.

use crate::{KnnResult, KnnScratch, Neighbours, entry_d2, offer};
use glam::{IVec3, Vec3};
use pm_format::PhotonRecord;
use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

/// Cells per largest search radius.
const CELLS_PER_RADIUS: f32 = 3.0;

/// A cheap hash for cell keys (three small integers): SipHash cost a fifth of a query.
#[derive(Default)]
struct CellHasher(u64);

impl Hasher for CellHasher {
    fn finish(&self) -> u64 {
        pm_sampling::mix64(self.0)
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(b as u64);
        }
    }
    fn write_i32(&mut self, v: i32) {
        self.write_u64(v as u32 as u64);
    }
    fn write_u64(&mut self, v: u64) {
        self.0 = (self.0 ^ v).wrapping_mul(0x9e37_79b9_7f4a_7c15).rotate_left(29);
    }
}

/// The grid.
#[derive(Clone, Debug)]
pub struct PhotonGrid<R> {
    cell: f32,
    records: Vec<Option<R>>,
    /// Where each id sits: its cell and position in the cell's list.
    place: Vec<Option<(IVec3, u32)>>,
    /// Each cell's photons: position and id (positions inline, so a query reads
    /// the records only of photons it keeps).
    cells: HashMap<IVec3, Vec<(Vec3, u32)>, BuildHasherDefault<CellHasher>>,
    /// Cell offsets within the largest search radius, nearest first, with a lower
    /// bound on the squared distance [cells^2] from any point of the centre cell.
    offsets: Vec<(IVec3, f32)>,
    /// The smallest and largest cell keys ever used (removals do not shrink them).
    extent: Option<(IVec3, IVec3)>,
}

/// The cell offsets within `reach` cells (Chebyshev), sorted by the lower bound on
/// the squared distance, in cells, from a point of the centre cell to the cell.
fn offsets(reach: i32) -> Vec<(IVec3, f32)> {
    let gap = |d: i32| (d.abs() - 1).max(0) as f32;
    let mut v: Vec<(IVec3, f32)> = (-reach..=reach)
        .flat_map(|z| (-reach..=reach).flat_map(move |y| (-reach..=reach).map(move |x| IVec3::new(x, y, z))))
        .map(|o| (o, gap(o.x).powi(2) + gap(o.y).powi(2) + gap(o.z).powi(2)))
        .collect();
    v.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.to_array().cmp(&b.0.to_array())));
    v
}

impl<R: PhotonRecord> PhotonGrid<R> {
    /// An empty grid for ids 0..`ids` whose queries search at most `radius` \[m\]
    /// (larger radii work, more slowly).
    pub fn new(radius: f32, ids: usize) -> PhotonGrid<R> {
        PhotonGrid {
            cell: (radius / CELLS_PER_RADIUS).max(f32::MIN_POSITIVE),
            records: vec![None; ids],
            place: vec![None; ids],
            cells: HashMap::default(),
            offsets: offsets(CELLS_PER_RADIUS as i32),
            extent: None,
        }
    }

    fn key_of(&self, p: Vec3) -> IVec3 {
        (p / self.cell).floor().as_ivec3()
    }

    /// Put `record` at `id` (or remove what is there with none).
    pub fn set(&mut self, id: u32, record: Option<R>) {
        if let Some((k, pos)) = self.place[id as usize].take() {
            let list = self.cells.get_mut(&k).expect("a placed id's cell exists");
            list.swap_remove(pos as usize);
            if let Some(&(_, moved)) = list.get(pos as usize) {
                self.place[moved as usize] = Some((k, pos));
            }
        }
        self.records[id as usize] = record;
        if let Some(r) = record {
            let k = self.key_of(r.position());
            self.extent = Some(self.extent.map_or((k, k), |(lo, hi)| (lo.min(k), hi.max(k))));
            let list = self.cells.entry(k).or_default();
            self.place[id as usize] = Some((k, list.len() as u32));
            list.push((r.position(), id));
        }
    }

    /// Photons held.
    pub fn len(&self) -> usize {
        self.place.iter().filter(|p| p.is_some()).count()
    }

    /// True when the grid holds none.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

impl<R: PhotonRecord> Neighbours<R> for PhotonGrid<R> {
    fn knn(
        &self,
        x: Vec3,
        k: usize,
        max_d2: f32,
        filter: impl Fn(u32, &R) -> bool,
        scratch: &mut KnnScratch,
    ) -> KnnResult {
        scratch.heap.clear();
        if k == 0 || !(max_d2 >= 0.0) {
            return KnnResult { count: 0, max_dist2: 0.0 };
        }
        let Some((lo, hi)) = self.extent else {
            return KnnResult { count: 0, max_dist2: 0.0 };
        };
        let c = self.key_of(x);
        // Cells beyond `reach` (Chebyshev, in cells) are out of the radius or empty.
        let to_extent = (c - lo).abs().max((hi - c).abs()).max_element();
        let reach = ((max_d2.sqrt() / self.cell).ceil().min(i32::MAX as f32 / 4.0) as i32).min(to_extent);
        let cell2 = self.cell * self.cell;
        // Lower bounds are shrunk a little against rounding (a photon's cell comes
        // from its position divided by the cell size).
        const SLACK: f32 = 1.0 - 1e-4;
        let heap = &mut scratch.heap;
        let bound = |heap: &std::collections::BinaryHeap<u64>| {
            if heap.len() < k { max_d2 } else { heap.peek().map_or(max_d2, |&e| entry_d2(e)) }
        };
        let visit = |o: IVec3, heap: &mut std::collections::BinaryHeap<u64>| {
            let kc = c + o;
            let corner = kc.as_vec3() * self.cell;
            let gap = (corner - x).max(x - (corner + Vec3::splat(self.cell))).max(Vec3::ZERO);
            if gap.length_squared() * SLACK > bound(heap) {
                return;
            }
            let Some(list) = self.cells.get(&kc) else { return };
            for &(p, i) in list {
                let d2 = p.distance_squared(x);
                if d2 > max_d2 {
                    continue;
                }
                offer(heap, k, d2, i, || {
                    filter(i, self.records[i as usize].as_ref().expect("a listed id has a photon"))
                });
            }
        };
        // The near cells nearest first, then shells of cells farther out.
        let near = CELLS_PER_RADIUS as i32;
        for &(o, lb) in &self.offsets {
            if lb * cell2 * SLACK > bound(heap) {
                break; // every later cell is at least as far
            }
            if o.abs().max_element() <= reach {
                visit(o, heap);
            }
        }
        for rho in near + 1..=reach {
            // Every cell of shell rho is at least rho - 1 cells from the centre cell.
            if ((rho - 1) as f32).powi(2) * cell2 * SLACK > bound(heap) {
                break;
            }
            for z in -rho..=rho {
                for y in -rho..=rho {
                    let inner = z.abs() < rho && y.abs() < rho;
                    let mut x = -rho;
                    while x <= rho {
                        visit(IVec3::new(x, y, z), heap);
                        x += if inner && x == -rho { 2 * rho } else { 1 };
                    }
                }
            }
        }
        // Lay the heap out from the sorted set, so the photons found are visited in
        // an order that depends on the set alone, not on the order ids were set in
        // (estimates then repeat exactly when the same photons are set again).
        let mut v = std::mem::take(heap).into_vec();
        v.sort_unstable();
        *heap = std::collections::BinaryHeap::from(v);
        KnnResult { count: heap.len(), max_dist2: heap.peek().map_or(0.0, |&e| entry_d2(e)) }
    }

    fn found<'s>(&'s self, scratch: &'s KnnScratch) -> impl Iterator<Item = (u32, f32)> + 's {
        scratch.found()
    }

    fn record(&self, i: u32) -> &R {
        self.records[i as usize].as_ref().expect("found ids have photons")
    }
}
