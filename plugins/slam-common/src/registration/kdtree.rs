//! A static k-d tree (Bentley, "Multidimensional binary search trees used for associative
//! searching", CACM 1975) for k-nearest-neighbour queries, searched as by Friedman, Bentley
//! and Finkel ("An algorithm for finding best matches in logarithmic expected time", ACM
//! TOMS 1977): the points are reordered in place so that every subrange's middle element
//! splits it along the axis of largest spread; small subranges are scanned linearly.
//!
//! One implementation for every dimension `D`: [`KdTree3`] for 3-d map points (LIO-SAM's
//! local map, [`crate::registration::icp`]) and [`KdTree2`] for planar scans ([`crate::registration::scan2d`]).
//!
//! Built once per map and queried many times, so building is a sort-like O(n log n) pass
//! with no allocation per node, and queries keep their k best in a small sorted array.
//! Deterministic: the same input gives the same tree and answers; of neighbours at equal
//! distances, the one the search reaches first comes first.

use nalgebra::SVector;

/// Subranges at most this long are leaves.
const LEAF: usize = 8;

/// A k-d tree over `D`-dimensional points. Indices returned by queries refer to
/// [`KdTree::point`].
#[derive(Debug, Clone, Default)]
pub struct KdTree<const D: usize> {
    points: Vec<SVector<f64, D>>,
    /// Split axis of the subrange whose middle element sits at this index.
    axis: Vec<u8>,
}

/// A k-d tree over 3-d points.
pub type KdTree3 = KdTree<3>;

/// A k-d tree over 2-d points.
pub type KdTree2 = KdTree<2>;

/// A neighbour: index into the tree's points and squared distance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Neighbour {
    pub index: usize,
    pub distance_sq: f64,
}

impl<const D: usize> KdTree<D> {
    pub fn new(mut points: Vec<SVector<f64, D>>) -> Self {
        let mut axis = vec![0u8; points.len()];
        build(&mut points, &mut axis);
        Self { points, axis }
    }

    pub fn len(&self) -> usize {
        self.points.len()
    }

    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    pub fn point(&self, index: usize) -> &SVector<f64, D> {
        &self.points[index]
    }

    pub fn points(&self) -> &[SVector<f64, D>] {
        &self.points
    }

    /// The `k` nearest points to `query` closer than `max_distance_sq` (squared), nearest
    /// first, written into `out` (cleared first).
    pub fn nearest(
        &self,
        query: &SVector<f64, D>,
        k: usize,
        max_distance_sq: f64,
        out: &mut Vec<Neighbour>,
    ) {
        out.clear();
        if k == 0 {
            return;
        }
        let mut search = Search {
            query,
            k,
            worst: max_distance_sq,
            out,
        };
        search.visit(self, 0, self.points.len());
    }

    /// The nearest point, if any is closer than `max_distance_sq` (squared).
    pub fn nearest_one(&self, query: &SVector<f64, D>, max_distance_sq: f64) -> Option<Neighbour> {
        let mut out = Vec::with_capacity(1);
        self.nearest(query, 1, max_distance_sq, &mut out);
        out.first().copied()
    }
}

fn build<const D: usize>(points: &mut [SVector<f64, D>], axis: &mut [u8]) {
    if points.len() <= LEAF {
        return;
    }
    let (lo, hi) = points.iter().fold(
        (
            SVector::<f64, D>::repeat(f64::INFINITY),
            SVector::<f64, D>::repeat(f64::NEG_INFINITY),
        ),
        |(lo, hi), p| (lo.inf(p), hi.sup(p)),
    );
    let a = (hi - lo).imax();
    let mid = points.len() / 2;
    points.select_nth_unstable_by(mid, |p, q| p[a].total_cmp(&q[a]));
    axis[mid] = a as u8;
    let (left, right) = points.split_at_mut(mid);
    let (axis_left, axis_right) = axis.split_at_mut(mid);
    build(left, axis_left);
    build(&mut right[1..], &mut axis_right[1..]);
}

struct Search<'a, const D: usize> {
    query: &'a SVector<f64, D>,
    k: usize,
    /// Squared distance a candidate must beat: the k-th best so far, or the limit.
    worst: f64,
    out: &'a mut Vec<Neighbour>,
}

impl<const D: usize> Search<'_, D> {
    #[inline(always)]
    fn offer(&mut self, index: usize, distance_sq: f64) {
        if distance_sq >= self.worst {
            return;
        }
        let at = self.out.partition_point(|n| n.distance_sq <= distance_sq);
        if self.out.len() == self.k {
            self.out.pop();
        }
        self.out.insert(at, Neighbour { index, distance_sq });
        if self.out.len() == self.k {
            self.worst = self.out[self.k - 1].distance_sq;
        }
    }

    fn visit(&mut self, tree: &KdTree<D>, lo: usize, hi: usize) {
        if hi - lo <= LEAF {
            for i in lo..hi {
                self.offer(i, (tree.points[i] - self.query).norm_squared());
            }
            return;
        }
        let mid = lo + (hi - lo) / 2;
        let a = tree.axis[mid] as usize;
        let p = &tree.points[mid];
        let gap = self.query[a] - p[a];
        let (near, far) = if gap < 0.0 {
            ((lo, mid), (mid + 1, hi))
        } else {
            ((mid + 1, hi), (lo, mid))
        };
        self.visit(tree, near.0, near.1);
        self.offer(mid, (p - self.query).norm_squared());
        if gap * gap < self.worst {
            self.visit(tree, far.0, far.1);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Vector2, Vector3};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Builds a tree of `n` points from `random` and checks the `k` nearest of 200 more
    /// within `max_distance_sq` against a linear scan.
    fn matches_brute_force<const D: usize>(
        n: usize,
        k: usize,
        max_distance_sq: f64,
        mut random: impl FnMut() -> SVector<f64, D>,
    ) {
        let points: Vec<_> = (0..n).map(|_| random()).collect();
        let tree = KdTree::new(points.clone());
        let mut out = Vec::new();
        for _ in 0..200 {
            let q = random();
            tree.nearest(&q, k, max_distance_sq, &mut out);
            let mut brute: Vec<f64> = points
                .iter()
                .map(|p| (p - q).norm_squared())
                .filter(|d| *d < max_distance_sq)
                .collect();
            brute.sort_by(f64::total_cmp);
            brute.truncate(k);
            let got: Vec<f64> = out.iter().map(|n| n.distance_sq).collect();
            assert_eq!(got, brute, "{k} nearest of {q:?}");
            for n in &out {
                assert_eq!((tree.point(n.index) - q).norm_squared(), n.distance_sq);
            }
        }
    }

    #[test]
    fn nearest_matches_brute_force_3d() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        matches_brute_force(5000, 5, 4.0, || {
            Vector3::new(
                rng.random_range(-10.0..10.0),
                rng.random_range(-10.0..10.0),
                rng.random_range(-1.0..1.0),
            )
        });
    }

    #[test]
    fn nearest_matches_brute_force_2d() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        matches_brute_force(3000, 4, 1.0, || {
            Vector2::new(rng.random_range(-10.0..10.0), rng.random_range(-10.0..10.0))
        });
    }
}
