//! Bounding volume hierarchy over the mesh triangles: binary build ([`build`]) split by binned
//! SAH ([`sah`]), collapsed to an 8-wide tree ([`collapse`]) traversed nearest child first
//! ([`traverse`]), its eight child boxes and a leaf's up to eight triangles each tested
//! together ([`kernel`]: AVX2 on CPUs that have it, chosen at run time; the portable kernel
//! elsewhere). Both kernels give the same hits bit for bit, as does every width and leaf
//! size: the closest hit under the tie rule is unique, so the tree's shape only changes the
//! speed.
//!
//! Layout: wide nodes of 256 bytes (four cache lines) in a flat `Vec`, depth-first; a leaf of
//! up to [`build::MAX_LEAF`] triangles lives in its parent's lane and indexes the precomputed
//! triangles, stored contiguous in leaf order, each leaf's row by row ([`LeafTriangles`]) so
//! that its triangles load side by side.
//!
//! Measured on the vineyard (`cargo bench -p vinebench-sim --bench raycast`, 2026-11-25, one
//! thread): the 4-wide SSE tree with leaves of 4 triangles tested one by one that this replaced
//! traced 3.05 M rays/s; 8-wide nodes with the AVX2 box test, 4.0 M (leaves of 8: 2–3% better
//! than of 4, in paired runs); with the leaf's triangles tested at once too, 4.85 M. (Each leaf
//! in a block of eight lanes, aligned, gave 5.0 M, but most leaves hold two triangles, so the
//! blocks took 14 MB against 4 MB for the packed rows.) The portable kernel on this tree traces
//! 2.6–2.7 M, slower than the 4-wide tree's 3.05 M: the price on CPUs without AVX2 (x86-64
//! before 2013, other architectures), which could get a 4-wide tree of their own. The traversal
//! is bound by the latency of its chain of node tests and branches, not by memory: nodes
//! quantized to 8 bits per plane (Ylitie, Karras & Laine 2017; half the cache lines), decoded
//! exactly and rounded outwards, were 1.4x slower with 4 children and with 8, the decoding
//! sitting on that chain. Spatial splits matter little here: Embree without them (its medium
//! quality) traces 5% slower than with.
//!
//! Tried before on the 4-wide tree and left out: packets of four rays of a lidar column
//! traversed together (Wald et al. 2001; 1.5x slower: the rays of a column diverge too fast to
//! share nodes), packets of eight rays of one laser ring over consecutive columns (0.2° apart,
//! so they share nearly every node; exact, and still 1.7x slower over a whole sweep: testing
//! every box against every ray costs more than the node fetches it saves), two rays of a fan
//! interleaved step by step (no gain: more branch mispredictions). SAH bins (16 or 32) made no
//! difference beyond noise, nor does the SAH's traversal-to-triangle cost ratio (0.5, 1, 2 on
//! the 8-wide tree). Also taken out: starting a lidar beam's traversal from its hit in the
//! previous column (exact, since the closest hit is unique under the tie rule; but in
//! criterion a sweep seeded so was 4–8% slower than one without, in every paired run: the
//! guessed triangle's lookup costs two cache misses, and nearest-first traversal finds that hit
//! early anyway).

pub(crate) mod build;
mod collapse;
mod kernel;
mod node;
mod sah;
mod traverse;

use nalgebra::{Point3, Vector3};

use super::ray::Ray;
use super::triangle::LeafTriangles;
use super::{Hit, RayCaster};
use crate::world::Mesh;
use kernel::Portable;
#[cfg(target_arch = "x86_64")]
use kernel::{Avx2, HasAvx2};
use node::{WIDTH, WideNode};
use traverse::{Entry, SMALL_STACK};

/// Binned-SAH BVH over a [`Mesh`]; see the module documentation.
#[derive(Clone, PartialEq)]
pub struct Bvh {
    /// Wide nodes, root first; empty when the mesh has no hittable triangle.
    nodes: Vec<WideNode>,
    /// The leaves' triangles, precomputed.
    triangles: LeafTriangles,
    /// Levels of wide nodes.
    depth: usize,
    /// Set when this CPU has AVX2: traversals then run the [`kernel::Avx2`] box test and are
    /// compiled for AVX2 (same hits as without).
    #[cfg(target_arch = "x86_64")]
    avx2: Option<HasAvx2>,
}

impl Bvh {
    /// Builds the hierarchy (in parallel with rayon for large meshes; the result is the same
    /// for any number of threads). Degenerate triangles are left out: no ray hits them.
    pub fn build(mesh: &Mesh) -> Self {
        build::build(mesh)
    }

    /// The tree from its parts, with the kernel this CPU runs best.
    fn from_parts(nodes: Vec<WideNode>, triangles: LeafTriangles, depth: usize) -> Self {
        Self {
            nodes,
            triangles,
            depth,
            #[cfg(target_arch = "x86_64")]
            avx2: HasAvx2::detect(),
        }
    }

    /// The same tree traversed with the portable kernel only (baseline x86-64's SSE on any
    /// CPU), to compare kernels: the hits are the same.
    pub fn portable(mut self) -> Self {
        #[cfg(target_arch = "x86_64")]
        {
            self.avx2 = None;
        }
        self
    }

    /// Whether traversals use the AVX2 kernel.
    pub fn uses_avx2(&self) -> bool {
        #[cfg(target_arch = "x86_64")]
        return self.avx2.is_some();
        #[cfg(not(target_arch = "x86_64"))]
        false
    }

    /// Number of (8-wide) nodes; 0 for a mesh with no hittable triangle.
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
        let mut out = [None];
        self.cast_fan(origin, std::slice::from_ref(dir), t_min, t_max, &mut out);
        out[0]
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
        let rays = Fan {
            origin,
            dirs,
            t_min,
            t_max,
        };
        let out = &mut out[..dirs.len()];
        self.with_stack(|stack| {
            #[cfg(target_arch = "x86_64")]
            if let Some(cpu) = self.avx2 {
                // SAFETY: `cpu` proves this CPU has AVX2.
                #[allow(unsafe_code)]
                unsafe {
                    fan_avx2(self, &rays, out, stack, cpu);
                }
                return;
            }
            fan(self, &rays, out, stack, |ray| Portable::new(ray, t_min));
        });
    }
}

/// The rays of one [`RayCaster::cast_fan`] call.
struct Fan<'a> {
    origin: &'a Point3<f32>,
    dirs: &'a [Vector3<f32>],
    t_min: f32,
    t_max: f32,
}

/// Casts every ray of the fan with the kernel `kernel` makes for it.
#[inline(always)]
fn fan<K: kernel::Kernel>(
    bvh: &Bvh,
    rays: &Fan<'_>,
    out: &mut [Option<Hit>],
    stack: &mut [Entry],
    kernel: impl Fn(&Ray) -> K,
) {
    for (slot, dir) in out.iter_mut().zip(rays.dirs) {
        let ray = Ray::new(rays.origin, dir);
        *slot = traverse::closest(bvh, kernel(&ray), rays.t_min, rays.t_max, stack);
    }
}

/// [`fan`] with the AVX2 kernel, the whole traversal compiled for AVX2.
///
/// # Safety
/// The CPU must have AVX2, which `cpu` proves.
#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)]
#[target_feature(enable = "avx2")]
unsafe fn fan_avx2(
    bvh: &Bvh,
    rays: &Fan<'_>,
    out: &mut [Option<Hit>],
    stack: &mut [Entry],
    cpu: HasAvx2,
) {
    fan(bvh, rays, out, stack, |ray| Avx2::new(ray, rays.t_min, cpu));
}
