//! Reference caster: every triangle for every ray.

use nalgebra::{Point3, Vector3};

use super::ray::Ray;
use super::triangle::{Triangle, hittable};
use super::{Hit, RayCaster};
use crate::world::Mesh;

/// Tests every triangle for every ray: the ground truth the [`super::Bvh`] is checked against.
/// Uses the same triangle test and the same tie rule, so the answers agree bit for bit.
#[derive(Clone)]
pub struct BruteForce {
    triangles: Vec<(Triangle, u32)>,
}

impl std::fmt::Debug for BruteForce {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BruteForce")
            .field("triangles", &self.triangles.len())
            .finish()
    }
}

impl BruteForce {
    pub fn build(mesh: &Mesh) -> Self {
        let triangles = hittable(mesh).map(|(id, _, t)| (t, id)).collect();
        Self { triangles }
    }
}

/// Whether a hit at `t` on triangle `id` beats the best so far: closer, or as close with a
/// smaller triangle index. The one rule shared by every caster here.
#[inline(always)]
pub(crate) fn better(t: f32, id: u32, best_t: f32, best_id: u32) -> bool {
    t < best_t || (t == best_t && id < best_id)
}

impl RayCaster for BruteForce {
    fn cast(
        &self,
        origin: &Point3<f32>,
        dir: &Vector3<f32>,
        t_min: f32,
        t_max: f32,
    ) -> Option<Hit> {
        let ray = Ray::new(origin, dir);
        let mut best: Option<Hit> = None;
        for &(tri, id) in &self.triangles {
            let Some(t) = tri.intersect(&ray) else {
                continue;
            };
            let (best_t, best_id) = best.map_or((t_max, u32::MAX), |h| (h.t, h.triangle));
            if t >= t_min && better(t, id, best_t, best_id) {
                best = Some(Hit { t, triangle: id });
            }
        }
        best
    }
}
