//! Ray casting into the static vineyard scene: the engine behind every simulated range sensor.
//!
//! - [`Bvh`]: the fast path, a binned-SAH bounding volume hierarchy over the mesh triangles
//!   (Wald 2007) collapsed to eight children per node, traversed nearest child first with an
//!   eight-box slab test (Williams et al. 2005; one AVX2 instruction per step where the CPU
//!   has it) and a Möller–Trumbore triangle test (Möller & Trumbore 1997) that divides only
//!   for a hit.
//! - [`ParryCaster`]: parry3d's `TriMesh`, an independent implementation to cross-check against.
//! - [`BruteForce`]: every triangle for every ray; the reference for tests.
//! - `EmbreeCaster` (cargo feature `embree`, on by default): Intel's Embree 3, the system's
//!   libembree3 (Debian's libembree-dev), through the `vinebench-embree` binding; one
//!   `rtcIntersect1` per ray (its packets showed no clear gain on lidar columns). The industry's
//!   kernel, to check the BVH against hit for hit and in rays per second.
//!
//! All answer the closest hit with the same rule: smallest `t` in `[t_min, t_max]`, ties
//! broken by the smaller triangle index, so results never depend on traversal order. The BVH,
//! parry3d and brute force share our triangle test; Embree rounds its own way, so its `t` can
//! differ in the last bits and, where two triangles are hit within that rounding (a shared
//! edge), it can name the other one (see `embree.rs`; sim/tests/all/embree.rs counts how often).

mod aabb;
mod brute;
mod bvh;
#[cfg(feature = "embree")]
mod embree;
mod parry;
mod ray;
mod triangle;

#[cfg(test)]
mod tests;

use nalgebra::{Point3, Vector3};

#[cfg(feature = "embree")]
pub use self::embree::{EmbreeCaster, FAN_PACKET as EMBREE_FAN_PACKET};
pub use brute::BruteForce;
pub use bvh::Bvh;
pub use parry::ParryCaster;

/// Closest intersection along a ray.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Distance along the unit direction, in metres.
    pub t: f32,
    /// Index of the triangle hit in the mesh the caster was built from.
    pub triangle: u32,
}

/// Anything that can cast rays into a fixed scene. Must be deterministic.
pub trait RayCaster: Send + Sync + std::fmt::Debug {
    /// Closest hit of origin + t * dir with t in [t_min, t_max]; `dir` is unit length, so t is
    /// the range in metres.
    fn cast(&self, origin: &Point3<f32>, dir: &Vector3<f32>, t_min: f32, t_max: f32)
    -> Option<Hit>;

    /// Many rays from ONE origin (a lidar column, a scan): fills `out[i]` for `dirs[i]`,
    /// exactly as [`Self::cast`] would, ray by ray. The default casts them one at a time.
    ///
    /// Panics if `out` is shorter than `dirs`.
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
        for (slot, dir) in out.iter_mut().zip(dirs) {
            *slot = self.cast(origin, dir, t_min, t_max);
        }
    }
}
