//! Closest-hit traversal of the 8-wide tree: iterative with an explicit stack, children
//! visited nearest first, leaves intersected as soon as their box is entered, and every box
//! entered beyond the best hit so far skipped.
//!
//! A traversal is a [`Walker`] advanced one node per [`Walker::step`]. (Interleaving the steps
//! of two rays of a fan was tried: the extra branch mispredictions ate the overlap.)

use super::Bvh;
use super::kernel::Kernel;
use super::node::WIDTH;
use crate::raycast::Hit;

/// Stack entries: a wide node still to visit and the distance at which the ray enters it.
pub(super) type Entry = (u32, f32);

/// Stack on the machine stack, enough for trees up to [`SMALL_STACK`] / ([`WIDTH`] - 1)
/// levels deep (all but pathological ones); deeper trees get a heap stack.
pub(super) const SMALL_STACK: usize = 64;

/// The state of one ray's traversal.
pub(super) struct Walker<'s, K> {
    kernel: K,
    best_t: f32,
    best_id: u32,
    /// Node to visit next; `None` when done.
    current: Option<u32>,
    stack: &'s mut [Entry],
    sp: usize,
}

impl<'s, K: Kernel> Walker<'s, K> {
    /// A traversal with no hit yet; `kernel` tests this ray against boxes and triangles.
    #[inline(always)]
    pub fn new(bvh: &Bvh, kernel: K, t_min: f32, t_max: f32, stack: &'s mut [Entry]) -> Self {
        let start = !bvh.nodes.is_empty() && t_min <= t_max;
        Self {
            kernel,
            best_t: t_max,
            best_id: u32::MAX,
            current: start.then_some(0),
            stack,
            sp: 0,
        }
    }

    pub fn hit(&self) -> Option<Hit> {
        (self.best_id != u32::MAX).then_some(Hit {
            t: self.best_t,
            triangle: self.best_id,
        })
    }

    /// Visits the current node and picks the next; returns whether there is one.
    #[inline(always)]
    pub fn step(&mut self, bvh: &Bvh) -> bool {
        let Some(current) = self.current else {
            return false;
        };
        let node = &bvh.nodes[current as usize];
        let (dist, mask) = self.kernel.boxes(node, self.best_t);
        // Leaves first, as soon as entered: a hit there prunes the inner children.
        let mut leaves = mask & node.leaves;
        let mut inner = mask & !node.leaves;
        while leaves != 0 {
            let lane = leaves.trailing_zeros() as usize;
            leaves &= leaves - 1;
            let before = self.best_t;
            self.leaf(bvh, node.child[lane], node.count[lane]);
            if self.best_t < before {
                inner &= closer_than(&dist, self.best_t);
            }
        }
        // (Bit tests rather than `count_ones`: baseline x86-64 has no popcnt instruction.)
        if inner != 0 {
            let a = inner.trailing_zeros() as usize;
            let rest = inner & (inner - 1);
            if rest == 0 {
                self.current = Some(node.child[a]);
                return true;
            }
            let b = rest.trailing_zeros() as usize;
            if rest & (rest - 1) == 0 {
                let (near, far) = if dist[b] < dist[a] { (b, a) } else { (a, b) };
                self.push(node.child[far], dist[far]);
                self.current = Some(node.child[near]);
                return true;
            }
            // More: sort (distance, lane) keys, push all but the nearest, farthest deepest.
            let mut keys = [0u64; WIDTH];
            let mut n = 0;
            while inner != 0 {
                let lane = inner.trailing_zeros();
                inner &= inner - 1;
                let key = u64::from(sortable(dist[lane as usize])) << 32 | u64::from(lane);
                // Insertion sort as the keys arrive.
                let mut j = n;
                while j > 0 && keys[j - 1] > key {
                    keys[j] = keys[j - 1];
                    j -= 1;
                }
                keys[j] = key;
                n += 1;
            }
            for &key in keys[1..n].iter().rev() {
                let lane = key as u32 as usize;
                self.push(node.child[lane], dist[lane]);
            }
            self.current = Some(node.child[keys[0] as u32 as usize]);
            return true;
        }
        // Pop the next node that may still hold a hit as good as the best one (a hit at the
        // same distance can still win on the triangle index).
        while self.sp > 0 {
            self.sp -= 1;
            let (n, t_entry) = self.stack[self.sp];
            if t_entry <= self.best_t {
                self.current = Some(n);
                return true;
            }
        }
        self.current = None;
        false
    }

    #[inline(always)]
    fn push(&mut self, node: u32, t_entry: f32) {
        self.stack[self.sp] = (node, t_entry);
        self.sp += 1;
    }

    /// Intersects the `count` triangles of a leaf from `first`, keeping the best hit.
    #[inline(always)]
    fn leaf(&mut self, bvh: &Bvh, first: u32, count: u8) {
        self.kernel.triangles(
            &bvh.triangles,
            first as usize,
            usize::from(count),
            &mut self.best_t,
            &mut self.best_id,
        );
    }
}

/// Closest hit of one ray (smallest `t` in `[t_min, t_max]`, ties to the smaller index).
#[inline(always)]
pub(super) fn closest<K: Kernel>(
    bvh: &Bvh,
    kernel: K,
    t_min: f32,
    t_max: f32,
    stack: &mut [Entry],
) -> Option<Hit> {
    let mut walker = Walker::new(bvh, kernel, t_min, t_max, stack);
    while walker.step(bvh) {}
    walker.hit()
}

/// Mask of the lanes whose entry distance is at most `t`.
#[inline(always)]
fn closer_than(dist: &[f32; WIDTH], t: f32) -> u32 {
    (0..WIDTH).fold(0, |m, i| m | u32::from(dist[i] <= t) << i)
}

/// The bits of `x` as an integer in the same order as the float (for finite values).
#[inline(always)]
fn sortable(x: f32) -> u32 {
    let b = x.to_bits();
    if b & 0x8000_0000 != 0 {
        !b
    } else {
        b | 0x8000_0000
    }
}
