//! One grapevine in vertical shoot positioning (VSP), the trellis system of the paper's
//! vineyard: a trunk up to the fruiting wire, two cordons along it, shoots growing up
//! between the catch wires with alternate leaves, and grape bunches below the cordon.
//!
//! The growth stage `g` ∈ [0, 4] is continuous: 0 dormant pruned wood (trunk, cordons,
//! spurs), 1 bud burst (short shoots, small leaves), 2 shoots half-grown, 3 dense canopy,
//! 4 full canopy with ripe bunches. Stage figures follow the modified Eichhorn–Lorenz
//! phenological scale (Coombe 1995) only loosely: they set sizes, not timings.

use nalgebra::{Point3, Vector3};
use rand::Rng;

use super::mesh::Material;
use super::mesh::Mesh;
use super::shapes::{bunch, leaf, polyline_tube};
use crate::rng::SimRng;

/// Draws uniform numbers for one plant as a blend of the clone's stream and the plant's own
/// stream: `u = u_clone + variation * (u_own - u_clone)`. With variation 0 every plant draws
/// exactly the clone's numbers (identical geometry); with 1 every plant its own.
#[derive(Debug)]
pub struct PlantRng {
    clone: SimRng,
    own: SimRng,
    variation: f64,
}

impl PlantRng {
    pub fn new(clone: SimRng, own: SimRng, variation: f64) -> Self {
        Self {
            clone,
            own,
            variation,
        }
    }

    /// Uniform in [0, 1).
    fn unit(&mut self) -> f64 {
        let a: f64 = self.clone.random();
        let b: f64 = self.own.random();
        a + self.variation * (b - a)
    }

    /// Uniform in [lo, hi).
    fn range(&mut self, lo: f64, hi: f64) -> f32 {
        (lo + (hi - lo) * self.unit()) as f32
    }

    /// Symmetric jitter in [-amount, amount).
    fn jitter(&mut self, amount: f64) -> f32 {
        self.range(-amount, amount)
    }
}

/// Where the plant sits in its trellis (local frame: x along the row, z up, ground at 0).
#[derive(Debug, Clone, Copy)]
pub struct VineLayout {
    pub spacing_m: f64,
    pub cordon_height_m: f64,
    pub canopy_top_m: f64,
    pub growth_stage: f64,
}

/// Fraction of a stage transition reached at stage `g`: 0 before `from`, 1 after `to`.
fn ramp(g: f64, from: f64, to: f64) -> f64 {
    ((g - from) / (to - from)).clamp(0.0, 1.0)
}

/// Builds one vine in its local frame.
pub fn vine(layout: &VineLayout, rng: &mut PlantRng) -> Mesh {
    let mut mesh = Mesh::new();
    let g = layout.growth_stage;
    let cordon_z = layout.cordon_height_m as f32;

    // Trunk: three slightly crooked segments from the ground to the fruiting wire.
    let mut trunk = vec![Point3::new(0.0, 0.0, -0.05)];
    for k in 1..=3 {
        let z = cordon_z * k as f32 / 3.0;
        trunk.push(Point3::new(rng.jitter(0.03), rng.jitter(0.03), z));
    }
    let head = Point3::new(0.0, 0.0, cordon_z);
    *trunk.last_mut().expect("trunk has points") = head;
    polyline_tube(&mut mesh, &trunk, rng.range(0.03, 0.045), 6, Material::Bark);

    // Two cordons along the wire, each nearly half the plant spacing long.
    let reach = (0.5 * layout.spacing_m - 0.06) as f32;
    let mut spur_points = Vec::new();
    for side in [-1.0f32, 1.0] {
        let mut cordon = vec![head];
        for k in 1..=4 {
            let x = side * reach * k as f32 / 4.0;
            cordon.push(Point3::new(
                x,
                rng.jitter(0.015),
                cordon_z + rng.jitter(0.015),
            ));
        }
        // Spurs every ~12 cm along the cordon.
        let spurs = (reach / 0.12).floor() as usize;
        for s in 0..spurs {
            let t = (s as f32 + 0.7) / spurs as f32;
            let i = ((t * 4.0).floor() as usize).min(3);
            let f = t * 4.0 - i as f32;
            spur_points.push(cordon[i] + (cordon[i + 1] - cordon[i]) * f);
        }
        polyline_tube(
            &mut mesh,
            &cordon,
            rng.range(0.018, 0.025),
            5,
            Material::Bark,
        );
    }

    // Shoots: a stub at dormancy, growing to the canopy top by stage 3.
    let max_shoot = (layout.canopy_top_m - layout.cordon_height_m).max(0.1);
    let shoot_length = (0.05 + (max_shoot - 0.05) * ramp(g, 0.5, 3.0)) as f32;
    let leaf_size = (0.04 + 0.10 * ramp(g, 1.0, 3.5)) as f32;
    let leaf_spacing = 0.075f32;
    let canopy_spread = (0.06 + 0.18 * ramp(g, 1.0, 3.5)) as f32;
    for &base in &spur_points {
        let length = shoot_length * rng.range(0.8, 1.1);
        let lean = Vector3::new(rng.jitter(0.15), rng.jitter(0.2), 1.0).normalize();
        let tip = base + lean * length;
        let mid =
            base + lean * (0.5 * length) + Vector3::new(rng.jitter(0.03), rng.jitter(0.04), 0.0);
        polyline_tube(
            &mut mesh,
            &[base, mid, tip],
            if g < 0.5 { 0.012 } else { 0.007 },
            4,
            Material::Bark,
        );
        if g < 0.8 {
            continue;
        }
        // Alternate leaves at the nodes, pushed out of the row plane by their petioles.
        let nodes = (length / leaf_spacing).floor() as usize;
        for n in 0..nodes {
            let along = (n as f32 + 0.6) * leaf_spacing;
            let at = base + lean * along;
            let side_sign = if n % 2 == 0 { 1.0 } else { -1.0 };
            let out = Vector3::new(rng.jitter(0.5), side_sign, rng.range(-0.2, 0.4)).normalize();
            let petiole = canopy_spread * rng.range(0.3, 1.0);
            let anchor = at + out * petiole;
            let droop =
                Vector3::new(rng.jitter(0.6), out.y * 0.4, rng.range(-1.0, 0.2)).normalize();
            let side = droop
                .cross(&Vector3::new(rng.jitter(0.3), rng.jitter(0.3), 1.0))
                .try_normalize(1e-6);
            let side = side.unwrap_or_else(Vector3::x);
            leaf(
                &mut mesh,
                anchor,
                droop,
                side,
                leaf_size * rng.range(0.7, 1.15),
                rng.range(0.1, 0.4),
            );
        }
        // Lateral shoots' small leaves fill the canopy from stage 2.5 on.
        if g > 2.5 {
            let laterals = ((g - 2.5) / 1.5 * nodes as f64 * 0.6).round() as usize;
            for _ in 0..laterals {
                let at = base + lean * (length * rng.range(0.15, 0.95));
                let out =
                    Vector3::new(rng.jitter(1.0), rng.jitter(1.0), rng.jitter(0.5)).normalize();
                let anchor = at + out * (canopy_spread * rng.range(0.2, 1.0));
                let dir = Vector3::new(rng.jitter(1.0), rng.jitter(1.0), rng.range(-1.0, 0.3))
                    .normalize();
                let side = dir
                    .cross(&out)
                    .try_normalize(1e-6)
                    .unwrap_or_else(Vector3::y);
                leaf(
                    &mut mesh,
                    anchor,
                    dir,
                    side,
                    0.7 * leaf_size * rng.range(0.7, 1.1),
                    0.2,
                );
            }
        }
    }

    // Bunches hang below the cordon from fruit set (stage 3) and swell to stage 4.
    let bunch_growth = ramp(g, 3.0, 4.0);
    if bunch_growth > 0.0 {
        for &base in spur_points.iter().step_by(2) {
            let length = (0.05 + 0.12 * bunch_growth) as f32 * rng.range(0.8, 1.2);
            let top = base + Vector3::new(rng.jitter(0.03), rng.jitter(0.06), -0.03);
            bunch(&mut mesh, top, length, 0.55 * length);
        }
    }
    mesh
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::stream;

    fn layout(g: f64) -> VineLayout {
        VineLayout {
            spacing_m: 1.0,
            cordon_height_m: 0.9,
            canopy_top_m: 1.9,
            growth_stage: g,
        }
    }

    fn build(g: f64) -> Mesh {
        let mut rng = PlantRng::new(stream(1, "clone"), stream(1, "own"), 0.0);
        vine(&layout(g), &mut rng)
    }

    #[test]
    fn canopy_grows_with_stage() {
        let counts: Vec<(usize, usize)> = [0.0, 1.0, 2.0, 3.0, 4.0]
            .iter()
            .map(|&g| {
                let m = build(g);
                let leaves = m.materials.iter().filter(|&&x| x == Material::Leaf).count();
                let grapes = m
                    .materials
                    .iter()
                    .filter(|&&x| x == Material::Grape)
                    .count();
                (leaves, grapes)
            })
            .collect();
        assert_eq!(
            counts[0],
            (0, 0),
            "dormant vine has neither leaves nor grapes"
        );
        for w in counts.windows(2) {
            assert!(
                w[1].0 > w[0].0,
                "leaf count must grow with stage: {counts:?}"
            );
        }
        assert!(
            counts[3].1 == 0 && counts[4].1 > 0,
            "grapes only at full stage: {counts:?}"
        );
        let top = build(4.0).bounds().expect("non-empty").1.z;
        assert!(
            top > 1.6,
            "full canopy reaches the catch wires, top at {top}"
        );
    }
}
