//! A uniform hash grid of photons that can be updated in place: the incremental
//! alternative to rebuilding the kd-tree every frame that Jozwowski 2002 (section
//! 4.4) names as future work. Photons are keyed by a caller's id (a ring-buffer
//! slot); setting an id replaces its photon. With cells as large as the search
//! radius, a k-nearest query reads the 27 cells around the query point.

use crate::{KnnResult, KnnScratch, Neighbours, key};
use glam::{IVec3, Vec3};
use pm_format::PhotonRecord;
use std::collections::HashMap;

/// The grid.
#[derive(Clone, Debug)]
pub struct PhotonGrid<R> {
    cell: f32,
    records: Vec<Option<R>>,
    /// Where each id sits: its cell and position in the cell's list.
    place: Vec<Option<(IVec3, u32)>>,
    cells: HashMap<IVec3, Vec<u32>>,
}

impl<R: PhotonRecord> PhotonGrid<R> {
    /// An empty grid for ids 0..`ids` with cells of side `cell` [m] (the largest
    /// search radius queries will use).
    pub fn new(cell: f32, ids: usize) -> PhotonGrid<R> {
        PhotonGrid {
            cell: cell.max(f32::MIN_POSITIVE),
            records: vec![None; ids],
            place: vec![None; ids],
            cells: HashMap::new(),
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
            if let Some(&moved) = list.get(pos as usize) {
                self.place[moved as usize] = Some((k, pos));
            }
        }
        self.records[id as usize] = record;
        if let Some(r) = record {
            let k = self.key_of(r.position());
            let list = self.cells.entry(k).or_default();
            self.place[id as usize] = Some((k, list.len() as u32));
            list.push(id);
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
        let reach = (max_d2.sqrt() / self.cell).ceil().clamp(1.0, 64.0) as i32;
        let c = self.key_of(x);
        let heap = &mut scratch.heap;
        for dz in -reach..=reach {
            for dy in -reach..=reach {
                for dx in -reach..=reach {
                    let Some(ids) = self.cells.get(&(c + IVec3::new(dx, dy, dz))) else { continue };
                    for &i in ids {
                        let r = self.records[i as usize].as_ref().expect("a listed id has a photon");
                        let d2 = r.position().distance_squared(x);
                        if d2 > max_d2 || !filter(i, r) {
                            continue;
                        }
                        if heap.len() < k {
                            heap.push((key(d2), i));
                        } else if let Some(mut top) = heap.peek_mut()
                            && (key(d2), i) < *top
                        {
                            *top = (key(d2), i);
                        }
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
        KnnResult { count: heap.len(), max_dist2: heap.peek().map_or(0.0, |t| f32::from_bits(t.0)) }
    }

    fn found<'s>(&'s self, scratch: &'s KnnScratch) -> impl Iterator<Item = (u32, f32)> + 's {
        scratch.found()
    }

    fn record(&self, i: u32) -> &R {
        self.records[i as usize].as_ref().expect("found ids have photons")
    }
}
