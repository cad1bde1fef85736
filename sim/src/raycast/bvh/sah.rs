//! Where to split a node: binned SAH after Wald (2007), "On fast construction of SAH-based
//! bounding volume hierarchies": the triangle centroids are sorted into [`BINS`] bins along
//! each axis and the plane between bins with the least surface-area-heuristic cost wins.

use super::build::{MAX_DEPTH, MAX_LEAF, Prims};
use crate::raycast::aabb::Aabb;

/// Below this depth nodes are split at the object median, which halves them, so a tree
/// of up to 2^32 triangles stays within [`MAX_DEPTH`] whatever the SAH does above.
const MEDIAN_DEPTH: usize = MAX_DEPTH - 32;
const BINS: usize = 32;
/// SAH costs of visiting a node and of testing a triangle.
const TRAVERSAL_COST: f32 = 1.0;
const INTERSECT_COST: f32 = 1.0;

/// Reorders `idx` into a left and a right part and returns the length of the left one, or
/// `None` if the node should be a leaf.
pub(super) fn split(prims: &Prims, idx: &mut [u32], depth: usize, bounds: &Aabb) -> Option<usize> {
    let n = idx.len();
    if n <= 1 {
        return None;
    }
    let mut centers = Aabb::EMPTY;
    for &k in idx.iter() {
        centers.grow_point(&prims.centers[k as usize]);
    }
    if depth >= MEDIAN_DEPTH {
        return (n > MAX_LEAF).then(|| median_split(prims, idx, &centers));
    }
    let Some(best) = best_binned_split(prims, idx, &centers) else {
        // All centroids coincide: no plane separates them.
        return (n > MAX_LEAF).then_some(n / 2);
    };
    let split_cost = TRAVERSAL_COST + INTERSECT_COST * best.cost / bounds.half_area().max(1e-30);
    if n <= MAX_LEAF && INTERSECT_COST * n as f32 <= split_cost {
        return None;
    }
    let bin = Binning::new(&centers, best.axis);
    let mid = partition(idx, |k| bin.of(&prims.centers[k as usize]) < best.bin);
    if mid == 0 || mid == n {
        // Rounding put every centroid on one side after all.
        return (n > MAX_LEAF).then(|| median_split(prims, idx, &centers));
    }
    Some(mid)
}

/// Splits at the object median along the longest axis of the centroid bounds.
fn median_split(prims: &Prims, idx: &mut [u32], centers: &Aabb) -> usize {
    let extent: [f32; 3] = std::array::from_fn(|k| centers.hi[k] - centers.lo[k]);
    let axis = (0..3).fold(0, |best, k| if extent[k] > extent[best] { k } else { best });
    let mid = idx.len() / 2;
    idx.select_nth_unstable_by(mid, |&a, &b| {
        let ca = prims.centers[a as usize][axis];
        let cb = prims.centers[b as usize][axis];
        ca.total_cmp(&cb).then(a.cmp(&b))
    });
    mid
}

/// Moves the entries satisfying `left` to the front (stable order is not needed, a fixed
/// one is) and returns their number.
fn partition(idx: &mut [u32], left: impl Fn(u32) -> bool) -> usize {
    let mut i = 0;
    let mut j = idx.len();
    while i < j {
        if left(idx[i]) {
            i += 1;
        } else {
            j -= 1;
            idx.swap(i, j);
        }
    }
    i
}

/// Maps centroids to bins along one axis of the centroid bounds.
struct Binning {
    axis: usize,
    lo: f32,
    scale: f32,
}

impl Binning {
    fn new(centers: &Aabb, axis: usize) -> Self {
        let extent = centers.hi[axis] - centers.lo[axis];
        Self {
            axis,
            lo: centers.lo[axis],
            scale: BINS as f32 / extent,
        }
    }

    fn of(&self, center: &[f32; 3]) -> usize {
        // `as` saturates (negative and NaN give 0); the top edge lands in the last bin.
        (((center[self.axis] - self.lo) * self.scale) as usize).min(BINS - 1)
    }
}

struct BestSplit {
    axis: usize,
    /// Triangles in bins `< bin` go left.
    bin: usize,
    /// Sum over both sides of half area times triangle count.
    cost: f32,
}

fn best_binned_split(prims: &Prims, idx: &[u32], centers: &Aabb) -> Option<BestSplit> {
    let mut best: Option<BestSplit> = None;
    for axis in 0..3 {
        let extent = centers.hi[axis] - centers.lo[axis];
        // (Never NaN: degenerate and non-finite triangles were left out.)
        if extent <= 0.0 {
            continue;
        }
        let binning = Binning::new(centers, axis);
        let mut counts = [0u32; BINS];
        let mut boxes = [Aabb::EMPTY; BINS];
        for &k in idx {
            let b = binning.of(&prims.centers[k as usize]);
            counts[b] += 1;
            boxes[b].grow(&prims.bounds[k as usize]);
        }
        // Left sweep: cost of the left side of the plane before bin i.
        let mut left_cost = [0.0f32; BINS];
        let mut left_count = [0u32; BINS];
        let (mut acc, mut cnt) = (Aabb::EMPTY, 0);
        for i in 1..BINS {
            acc.grow(&boxes[i - 1]);
            cnt += counts[i - 1];
            left_cost[i] = acc.half_area() * cnt as f32;
            left_count[i] = cnt;
        }
        let (mut acc, mut cnt) = (Aabb::EMPTY, 0);
        for i in (1..BINS).rev() {
            acc.grow(&boxes[i]);
            cnt += counts[i];
            if cnt == 0 || left_count[i] == 0 {
                continue;
            }
            let cost = left_cost[i] + acc.half_area() * cnt as f32;
            if best.as_ref().is_none_or(|b| cost < b.cost) {
                best = Some(BestSplit { axis, bin: i, cost });
            }
        }
    }
    best
}
