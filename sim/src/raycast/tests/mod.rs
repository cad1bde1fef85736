//! Unit tests of the ray casters, on seeded random scenes.

mod brute_force;
mod determinism;
mod edge_cases;
mod parry;

use nalgebra::{Point3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::world::{Material, Mesh};

pub(super) fn rng(seed: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed)
}

pub(super) fn point_in(rng: &mut impl Rng, lo: f32, hi: f32) -> Point3<f32> {
    Point3::new(
        rng.random_range(lo..hi),
        rng.random_range(lo..hi),
        rng.random_range(lo..hi),
    )
}

/// Uniform on the unit sphere (rejection from the cube).
pub(super) fn unit_dir(rng: &mut impl Rng) -> Vector3<f32> {
    loop {
        let v = point_in(rng, -1.0, 1.0).coords;
        let n2 = v.norm_squared();
        if n2 > 1e-4 && n2 <= 1.0 {
            return v / n2.sqrt();
        }
    }
}

/// `n` triangles with corners within `size` of a random point of the cube `[-half, half]^3`.
pub(super) fn soup(rng: &mut impl Rng, n: usize, half: f32, size: f32) -> Mesh {
    let mut mesh = Mesh::new();
    for _ in 0..n {
        let c = point_in(rng, -half, half);
        let tri = [0, 1, 2].map(|_| mesh.push_vertex(c + point_in(rng, -size, size).coords));
        mesh.push_triangle(tri, Material::Leaf);
    }
    mesh
}

/// A ground plane z = 0 of `cells` x `cells` unit squares (two triangles each), centred.
pub(super) fn grid(cells: u32) -> Mesh {
    let mut mesh = Mesh::new();
    let half = cells as f32 / 2.0;
    for j in 0..=cells {
        for i in 0..=cells {
            mesh.push_vertex(Point3::new(i as f32 - half, j as f32 - half, 0.0));
        }
    }
    let at = |i: u32, j: u32| j * (cells + 1) + i;
    for j in 0..cells {
        for i in 0..cells {
            mesh.push_triangle([at(i, j), at(i + 1, j), at(i + 1, j + 1)], Material::Soil);
            mesh.push_triangle([at(i, j), at(i + 1, j + 1), at(i, j + 1)], Material::Soil);
        }
    }
    mesh
}
