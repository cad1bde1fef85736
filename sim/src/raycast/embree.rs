//! Intel's Embree 3 (the system's libembree3, through `vinebench-embree`) behind
//! [`RayCaster`]: `raycaster = "embree"`, the industry's ray kernel to set our [`super::Bvh`]
//! against, hit for hit and in rays per second.
//!
//! Built from the same hittable triangles as the other casters; Embree's triangle index
//! (primID) is the position in that list, mapped back to the mesh index. Fans go to Embree
//! as [`FAN_PACKET`] says (single rays: packets measured no faster).
//!
//! # Where it can differ from the BVH
//! - `t`: Embree's Möller–Trumbore divides with a Newton-refined approximate reciprocal where
//!   ours divides exactly, so the same hit can differ in the last bits of `t` (the tests bound
//!   it), and between CPU families (Embree picks SSE/AVX/AVX2/AVX-512 kernels at run time).
//! - Near-ties: a ray through the edge two triangles share hits both at nearly the same `t`;
//!   each caster keeps its own closest, and when the two `t` differ only in rounding the two
//!   casters can name different triangles (exact ties go to the smaller index in both: the
//!   binding installs an Embree intersection filter that applies our rule).
//! - Interval ends: Embree accepts `t_min < t <= t_max` tested in scaled form
//!   (`|den| t_min < T`), ours `t_min <= t <= t_max` on the divided `t`.
//! - Grazing rays: ours misses a triangle when `|cos|` between ray and plane normal is below
//!   1e-6; Embree only when it is exactly 0.

use ::embree::{Packet, Scene, SceneOptions};
use nalgebra::{Point3, Vector3};

use super::triangle::hittable;
use super::{Hit, RayCaster};
use crate::world::Mesh;

/// How fans go to Embree: one `rtcIntersect1` per ray. Packets did not pay clearly on the
/// default world's VLP-16 columns (16 beams spread over 30 degrees from one origin, which
/// diverge too fast to stay coherent): on this 2-core AVX2 machine, busy, rtcIntersect4/8/16
/// ran from 4 % slower to 8 % faster than single rays depending on the run. The
/// `rays_one_thread` bench runs all four, so the choice can be checked on a quiet machine.
pub const FAN_PACKET: Packet = Packet::Single;

/// An Embree scene of the hittable triangles of a [`Mesh`].
#[derive(Debug)]
pub struct EmbreeCaster {
    scene: Scene,
    /// Mesh index of each Embree triangle (ascending, so Embree's tie rule on its indices is
    /// ours on mesh indices).
    ids: Vec<u32>,
    fan_packet: Packet,
}

impl EmbreeCaster {
    /// Embree's best-tracing hierarchy (spatial-split SAH), built on one thread so the build
    /// does not depend on the machine.
    pub fn build(mesh: &Mesh) -> Result<Self, ::embree::EmbreeError> {
        Self::with_options(mesh, SceneOptions::default(), FAN_PACKET)
    }

    /// As [`EmbreeCaster::build`] with Embree's build options and fan packet width chosen (for
    /// benches and tests).
    pub fn with_options(
        mesh: &Mesh,
        options: SceneOptions,
        fan_packet: Packet,
    ) -> Result<Self, ::embree::EmbreeError> {
        let vertices: Vec<[f32; 3]> = mesh.vertices.iter().map(|p| [p.x, p.y, p.z]).collect();
        let mut indices = Vec::new();
        let mut ids = Vec::new();
        for (id, _, _) in hittable(mesh) {
            indices.push(mesh.triangles[id as usize]);
            ids.push(id);
        }
        let scene = Scene::new(&vertices, &indices, options)?;
        Ok(Self {
            scene,
            ids,
            fan_packet,
        })
    }

    fn hit(&self, h: ::embree::Hit) -> Hit {
        Hit {
            t: h.t,
            triangle: self.ids[h.prim as usize],
        }
    }
}

impl RayCaster for EmbreeCaster {
    fn cast(
        &self,
        origin: &Point3<f32>,
        dir: &Vector3<f32>,
        t_min: f32,
        t_max: f32,
    ) -> Option<Hit> {
        self.scene
            .intersect(origin.coords.into(), (*dir).into(), t_min, t_max)
            .map(|h| self.hit(h))
    }

    /// Fans go to Embree as the caster was built to send them ([`FAN_PACKET`] by default).
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
        const CHUNK: usize = 16;
        let mut d = [[0.0f32; 3]; CHUNK];
        let mut h = [None; CHUNK];
        for (dirs, out) in dirs.chunks(CHUNK).zip(out.chunks_mut(CHUNK)) {
            for (d, dir) in d.iter_mut().zip(dirs) {
                *d = (*dir).into();
            }
            let n = dirs.len();
            self.scene.intersect_fan(
                origin.coords.into(),
                &d[..n],
                t_min,
                t_max,
                self.fan_packet,
                &mut h[..n],
            );
            for (slot, hit) in out.iter_mut().zip(&h[..n]) {
                *slot = hit.map(|hit| self.hit(hit));
            }
        }
    }
}
