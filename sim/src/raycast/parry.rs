//! parry3d's `TriMesh` behind [`RayCaster`]: an independent implementation to cross-check the
//! [`super::Bvh`] against (and a fallback). About six times slower.

use nalgebra::{Point3, Vector3};
use parry3d::math::Vector as PVector;
use parry3d::query::{PointQuery, Ray as PRay, RayCast};
use parry3d::shape::TriMesh;

use super::triangle::hittable;
use super::{Hit, RayCaster};
use crate::world::Mesh;

/// A parry3d [`TriMesh`] of the hittable triangles of a [`Mesh`].
#[derive(Clone)]
pub struct ParryCaster {
    /// `None` when the mesh has no hittable triangle (parry rejects an empty mesh).
    trimesh: Option<TriMesh>,
    /// Mesh index of each parry triangle (degenerate triangles are left out, as in the BVH).
    ids: Vec<u32>,
}

impl std::fmt::Debug for ParryCaster {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ParryCaster")
            .field("triangles", &self.ids.len())
            .finish_non_exhaustive()
    }
}

impl ParryCaster {
    pub fn build(mesh: &Mesh) -> Self {
        let vertices: Vec<PVector> = mesh
            .vertices
            .iter()
            .map(|p| PVector::new(p.x, p.y, p.z))
            .collect();
        let mut indices = Vec::new();
        let mut ids = Vec::new();
        for (id, _, _) in hittable(mesh) {
            indices.push(mesh.triangles[id as usize]);
            ids.push(id);
        }
        let trimesh = if indices.is_empty() {
            None
        } else {
            Some(TriMesh::new(vertices, indices).expect("non-empty mesh of valid triangles"))
        };
        Self { trimesh, ids }
    }

    /// Distance from `p` to the closest point of any triangle (infinite for an empty mesh):
    /// a geometry query for tests, e.g. whether lidar points lie on the scene's surfaces.
    pub fn distance_to_surface(&self, p: &Point3<f32>) -> f32 {
        self.trimesh.as_ref().map_or(f32::INFINITY, |m| {
            m.distance_to_local_point(PVector::new(p.x, p.y, p.z), false)
        })
    }
}

impl RayCaster for ParryCaster {
    fn cast(
        &self,
        origin: &Point3<f32>,
        dir: &Vector3<f32>,
        t_min: f32,
        t_max: f32,
    ) -> Option<Hit> {
        let trimesh = self.trimesh.as_ref()?;
        // An empty or NaN interval has no hit.
        if t_min.partial_cmp(&t_max).is_none_or(|o| o.is_gt()) {
            return None;
        }
        // parry has no t_min: start the ray there instead.
        let start = origin + dir * t_min;
        let ray = PRay::new(
            PVector::new(start.x, start.y, start.z),
            PVector::new(dir.x, dir.y, dir.z),
        );
        let hit = trimesh.cast_local_ray_and_get_normal(&ray, t_max - t_min, false)?;
        Some(Hit {
            t: hit.time_of_impact + t_min,
            triangle: self.ids[hit.subshape as usize],
        })
    }
}
