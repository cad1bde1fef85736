//! Bounding volume hierarchy over the mesh triangles: binary build ([`build`]) split by binned
//! SAH ([`sah`]), collapsed to a 4-wide tree ([`collapse`]) whose four child boxes are tested
//! together (one SSE instruction per step), traversed nearest child first ([`traverse`]).
//!
//! Layout: wide nodes of 128 bytes (two cache lines) in a flat `Vec`, depth-first; leaves of
//! up to [`build::MAX_LEAF`] triangles live in their parent's lanes and index the precomputed
//! triangles, stored contiguous in leaf order.
//!
//! Tried on the vineyard benchmark and left out: 8-wide nodes (about 5% slower: more cache
//! lines per node), packets of four rays of a lidar column traversed together (Wald et al.
//! 2001; 1.5x slower: the rays of a column diverge too fast to share nodes), packets of eight
//! rays of one laser ring over consecutive columns (0.2° apart, so they share nearly every
//! node; exact, and still 1.7x slower over a whole sweep: with baseline x86-64's 4-wide SSE,
//! testing every box against every ray costs more than the node fetches it saves), two rays of a fan
//! interleaved step by step (no gain: more branch mispredictions). SAH bins (16 or 32) and
//! leaf sizes (4 or 8) made no difference beyond noise, nor did building for x86-64-v3
//! (AVX2). Also taken out: starting a lidar beam's traversal from its hit in the previous
//! column (exact, since the closest hit is unique under the tie rule; but in criterion a
//! sweep seeded so was 4–8% slower than one without, in every paired run: the guessed
//! triangle's lookup costs two cache misses, and nearest-first traversal finds that hit
//! early anyway).

pub(crate) mod build;
mod collapse;
mod node;
mod sah;
mod traverse;

use nalgebra::{Point3, Vector3};

use super::ray::Ray;
use super::triangle::Triangle;
use super::{Hit, RayCaster};
use crate::world::Mesh;
use node::{WIDTH, WideNode};
use traverse::{Entry, SMALL_STACK};

/// Binned-SAH BVH over a [`Mesh`]; see the module documentation.
#[derive(Clone, PartialEq)]
pub struct Bvh {
    /// Wide nodes, root first; empty when the mesh has no hittable triangle.
    nodes: Vec<WideNode>,
    /// Precomputed triangles in leaf order.
    triangles: Vec<Triangle>,
    /// Mesh index of each entry of `triangles`.
    ids: Vec<u32>,
    /// Levels of wide nodes.
    depth: usize,
}

impl Bvh {
    /// Builds the hierarchy (in parallel with rayon for large meshes; the result is the same
    /// for any number of threads). Degenerate triangles are left out: no ray hits them.
    pub fn build(mesh: &Mesh) -> Self {
        build::build(mesh)
    }

    /// Number of (4-wide) nodes; 0 for a mesh with no hittable triangle.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Number of triangles in the hierarchy (degenerate ones are not).
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// Levels of wide nodes (0 for an empty tree, 1 for a root alone).
    pub fn depth(&self) -> usize {
        self.depth
    }

    /// The same tree claiming `depth` levels, to test the heap traversal stack.
    #[cfg(test)]
    pub(crate) fn with_depth_for_test(mut self, depth: usize) -> Self {
        assert!(
            depth >= self.depth,
            "a tree can only claim more levels than it has"
        );
        self.depth = depth;
        self
    }

    /// Runs `f` with a traversal stack large enough for this tree.
    fn with_stack<R>(&self, f: impl FnOnce(&mut [Entry]) -> R) -> R {
        if self.stack_size() <= SMALL_STACK {
            f(&mut [(0, 0.0); SMALL_STACK])
        } else {
            f(&mut vec![(0, 0.0); self.stack_size()])
        }
    }

    /// Traversal stack entries this tree can need: each level pushes all its children but one.
    fn stack_size(&self) -> usize {
        (WIDTH - 1) * self.depth
    }
}

/// A summary: the tree itself would print megabytes.
impl std::fmt::Debug for Bvh {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Bvh")
            .field("nodes", &self.nodes.len())
            .field("triangles", &self.triangles.len())
            .field("depth", &self.depth())
            .finish()
    }
}

impl RayCaster for Bvh {
    fn cast(
        &self,
        origin: &Point3<f32>,
        dir: &Vector3<f32>,
        t_min: f32,
        t_max: f32,
    ) -> Option<Hit> {
        let ray = Ray::new(origin, dir);
        self.with_stack(|stack| traverse::closest(self, ray, t_min, t_max, stack))
    }

    /// Same answers as [`Bvh::cast`] ray by ray, with one traversal stack for the whole fan.
    /// Consecutive directions that are close (one laser ring at a time rather than one
    /// column) share more of the tree in cache and run about 10% faster.
    fn cast_fan(
        &self,
        origin: &Point3<f32>,
        dirs: &[Vector3<f32>],
        t_min: f32,
        t_max: f32,
        out: &mut [Option<Hit>],
    ) {
        assert!(
            out.len() >= dirs.len(),
            "cast_fan: `out` shorter than `dirs`"
        );
        self.with_stack(|stack| {
            for (slot, dir) in out.iter_mut().zip(dirs) {
                *slot = traverse::closest(self, Ray::new(origin, dir), t_min, t_max, stack);
            }
        });
    }
}
