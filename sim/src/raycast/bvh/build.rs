//! Top-down build of the binary tree, each node split where [`split`] says (binned SAH,
//! Wald 2007). The binary tree is then collapsed into the 8-wide tree that is traversed
//! ([`super::collapse`]).
//!
//! Subtrees of at least [`PARALLEL_MIN`] triangles are built in parallel with rayon and
//! spliced in the order a sequential build would have written them, so the tree is the same
//! for any number of threads.

use super::node::{Node, NodePair, WideNode};
use super::sah::split;
use super::{Bvh, collapse};
use crate::raycast::aabb::Aabb;
use crate::raycast::triangle::{BLOCK, LeafTriangles, Triangle, hittable};
use crate::world::Mesh;

/// Most triangles in a leaf: one SIMD register of each row of [`LeafTriangles`].
pub(crate) const MAX_LEAF: usize = BLOCK;
/// Deepest leaf the binary tree can have (see [`super::sah`]).
pub(crate) const MAX_DEPTH: usize = 80;
const PARALLEL_MIN: usize = 8192;

/// What the build needs of a triangle.
pub(super) struct Prims {
    pub bounds: Vec<Aabb>,
    pub centers: Vec<[f32; 3]>,
}

pub(super) fn build(mesh: &Mesh) -> Bvh {
    let mut tris = Vec::with_capacity(mesh.triangles.len());
    let mut ids = Vec::with_capacity(mesh.triangles.len());
    let mut prims = Prims {
        bounds: Vec::with_capacity(mesh.triangles.len()),
        centers: Vec::with_capacity(mesh.triangles.len()),
    };
    for (id, [a, b, c], tri) in hittable(mesh) {
        let bounds = Triangle::bounds(&a, &b, &c);
        tris.push(tri);
        ids.push(id);
        prims.centers.push(bounds.center());
        prims.bounds.push(bounds);
    }
    if tris.is_empty() {
        return Bvh::from_parts(Vec::new(), LeafTriangles::new(&[], &[], &[], &[]), 0);
    }
    let mut order: Vec<u32> = (0..u32::try_from(tris.len()).expect("checked above")).collect();
    let (root, pairs) = subtree(&prims, &mut order, 0, 0);
    let (nodes, depth) = collapse::collapse(&root, &pairs);
    let triangles = LeafTriangles::new(&tris, &ids, &order, &leaves(&nodes));
    Bvh::from_parts(nodes, triangles, depth)
}

/// Every leaf of the tree as `(first, n)` in leaf order.
fn leaves(nodes: &[WideNode]) -> Vec<(usize, usize)> {
    nodes
        .iter()
        .flat_map(|node| {
            (0..node.child.len())
                .filter(|&lane| node.leaves & (1 << lane) != 0)
                .map(|lane| (node.child[lane] as usize, usize::from(node.count[lane])))
        })
        .collect()
}

/// Builds the subtree over `idx` (which starts at `first` in the leaf order), in parallel
/// when it is large. Returns its root and its node pairs, child pointers relative to them.
fn subtree(prims: &Prims, idx: &mut [u32], first: u32, depth: usize) -> (Node, Vec<NodePair>) {
    if idx.len() < PARALLEL_MIN {
        let mut pairs = Vec::new();
        let root = sequential(prims, idx, first, depth, &mut pairs);
        return (root, pairs);
    }
    let bounds = bounds_of(prims, idx);
    let Some(mid) = split(prims, idx, depth, &bounds) else {
        return (leaf(&bounds, first, idx.len()), Vec::new());
    };
    let (left, right) = idx.split_at_mut(mid);
    let mid = u32::try_from(mid).expect("fits: idx has u32 entries");
    let ((l, l_pairs), (r, r_pairs)) = rayon::join(
        || subtree(prims, left, first, depth + 1),
        || subtree(prims, right, first + mid, depth + 1),
    );
    // Lay out as `sequential` does: the children's pair, the left subtree, the right one.
    let l_shift = 1;
    let r_shift = 1 + u32::try_from(l_pairs.len()).expect("node count fits u32");
    let mut pairs = Vec::with_capacity(1 + l_pairs.len() + r_pairs.len());
    pairs.push(NodePair([shifted(l, l_shift), shifted(r, r_shift)]));
    pairs.extend(
        l_pairs
            .iter()
            .map(|p| NodePair(p.0.map(|n| shifted(n, l_shift)))),
    );
    pairs.extend(
        r_pairs
            .iter()
            .map(|p| NodePair(p.0.map(|n| shifted(n, r_shift)))),
    );
    (interior(&bounds, 0), pairs)
}

/// Builds the subtree over `idx` depth first, appending its pairs to `pairs`.
fn sequential(
    prims: &Prims,
    idx: &mut [u32],
    first: u32,
    depth: usize,
    pairs: &mut Vec<NodePair>,
) -> Node {
    let bounds = bounds_of(prims, idx);
    let Some(mid) = split(prims, idx, depth, &bounds) else {
        return leaf(&bounds, first, idx.len());
    };
    let slot = pairs.len();
    pairs.push(NodePair([leaf(&bounds, 0, 0); 2]));
    let (left, right) = idx.split_at_mut(mid);
    let mid = u32::try_from(mid).expect("fits: idx has u32 entries");
    let l = sequential(prims, left, first, depth + 1, pairs);
    let r = sequential(prims, right, first + mid, depth + 1, pairs);
    pairs[slot] = NodePair([l, r]);
    interior(&bounds, u32::try_from(slot).expect("node count fits u32"))
}

fn bounds_of(prims: &Prims, idx: &[u32]) -> Aabb {
    let mut b = Aabb::EMPTY;
    for &k in idx {
        b.grow(&prims.bounds[k as usize]);
    }
    b
}

fn leaf(bounds: &Aabb, first: u32, count: usize) -> Node {
    let b = bounds.padded();
    Node {
        lo: b.lo,
        first,
        hi: b.hi,
        count: u32::try_from(count).expect("leaf holds at most MAX_LEAF"),
    }
}

fn interior(bounds: &Aabb, pair: u32) -> Node {
    leaf(bounds, pair, 0)
}

fn shifted(mut node: Node, by: u32) -> Node {
    if node.count == 0 {
        node.first += by;
    }
    node
}
