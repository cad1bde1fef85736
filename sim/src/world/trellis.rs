//! Posts and trellis wires of one row.

use nalgebra::Point3;

use super::mesh::{Material, Mesh};
use super::shapes::{post, tube};
use super::terrain::Terrain;
use crate::config::VineyardConfig;

/// x positions of a row's posts: at both ends and about every `post_spacing_m` between.
pub fn post_xs(v: &VineyardConfig) -> Vec<f64> {
    let spans = (v.row_length_m / v.post_spacing_m).round().max(1.0) as usize;
    (0..=spans)
        .map(|i| v.row_length_m * i as f64 / spans as f64)
        .collect()
}

/// Appends the posts and wires of the row at `y`; returns the posts' ground points.
pub fn row_trellis(
    mesh: &mut Mesh,
    v: &VineyardConfig,
    terrain: &Terrain,
    y: f64,
) -> Vec<Point3<f64>> {
    let xs = post_xs(v);
    let feet: Vec<Point3<f64>> = xs
        .iter()
        .map(|&x| Point3::new(x, y, terrain.height(x, y)))
        .collect();
    for (i, foot) in feet.iter().enumerate() {
        // End posts carry the wire tension and are stouter.
        let width = if i == 0 || i + 1 == feet.len() {
            0.12
        } else {
            0.08
        };
        post(mesh, foot.cast(), width, v.post_height_m as f32);
    }
    for &h in &v.wire_heights_m {
        for pair in feet.windows(2) {
            let a = pair[0] + nalgebra::Vector3::z() * h;
            let b = pair[1] + nalgebra::Vector3::z() * h;
            tube(mesh, a.cast(), b.cast(), 0.0025, 3, false, Material::Wire);
        }
    }
    feet
}
