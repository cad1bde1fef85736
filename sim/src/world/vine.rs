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
    // From stage 3 to 4 the canopy closes into a leaf wall, as a VSP canopy at full growth
    // (about 15 shoots per metre of row, two to four leaf layers): each spur's second bud
    // grows a shoot, laterals multiply and leaves reach full size. Nothing of this exists
    // up to stage 3, whose plants are unchanged.
    let full = ramp(g, 3.0, 4.0);
    let leaf_size = (0.04 + 0.10 * ramp(g, 1.0, 3.5) + FULL_LEAF_GAIN_M * full) as f32;
    let leaf_spacing = 0.075f32;
    let canopy_spread = (0.06 + 0.18 * ramp(g, 1.0, 3.5)) as f32;
    let lateral_ramp = (g - 2.5) / 1.5;
    let extra_laterals_per_node = FULL_LATERALS_PER_NODE * full;
    let lateral_size = (0.7 + 0.2 * full) as f32;
    let buds = if full > 0.0 { 2 } else { 1 };
    for &base in &spur_points {
        for bud in 0..buds {
            // The second bud's shoot grows from stage 3 and starts a little along the spur.
            let (base, grown) = if bud == 0 {
                (base, 1.0)
            } else {
                (
                    base + Vector3::new(rng.jitter(0.03), rng.jitter(0.03), 0.02),
                    full as f32,
                )
            };
            shoot(
                &mut mesh,
                rng,
                &Shoot {
                    base,
                    length: shoot_length * grown,
                    thick: g < 0.5,
                    leaves: g >= 0.8,
                    leaf_spacing,
                    leaf_size,
                    canopy_spread,
                    lateral_ramp,
                    extra_laterals_per_node,
                    lateral_size,
                    laterals: g > 2.5,
                },
            );
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

/// Leaf size added from stage 3 to 4 (m): full-grown leaves.
const FULL_LEAF_GAIN_M: f64 = 0.03;
/// Lateral leaves per main-shoot node added from stage 3 to 4.
const FULL_LATERALS_PER_NODE: f64 = 1.5;

/// One shoot's parameters (see [`vine`]).
#[derive(Debug, Clone, Copy)]
struct Shoot {
    base: Point3<f32>,
    length: f32,
    /// A dormant spur's stub (thicker than a green shoot).
    thick: bool,
    /// Whether it carries leaves yet.
    leaves: bool,
    leaf_spacing: f32,
    leaf_size: f32,
    canopy_spread: f32,
    /// Whether lateral shoots' leaves have started; their count per node is
    /// `0.6 lateral_ramp + extra_laterals_per_node`.
    laterals: bool,
    lateral_ramp: f64,
    extra_laterals_per_node: f64,
    /// Lateral leaves' size relative to the main leaves.
    lateral_size: f32,
}

/// A shoot with its alternate leaves and its laterals' leaves.
fn shoot(mesh: &mut Mesh, rng: &mut PlantRng, s: &Shoot) {
    let base = s.base;
    let length = s.length * rng.range(0.8, 1.1);
    let lean = Vector3::new(rng.jitter(0.15), rng.jitter(0.2), 1.0).normalize();
    let tip = base + lean * length;
    let mid = base + lean * (0.5 * length) + Vector3::new(rng.jitter(0.03), rng.jitter(0.04), 0.0);
    polyline_tube(
        mesh,
        &[base, mid, tip],
        if s.thick { 0.012 } else { 0.007 },
        4,
        Material::Bark,
    );
    if !s.leaves {
        return;
    }
    // Alternate leaves at the nodes, pushed out of the row plane by their petioles.
    let nodes = (length / s.leaf_spacing).floor() as usize;
    for n in 0..nodes {
        let along = (n as f32 + 0.6) * s.leaf_spacing;
        let at = base + lean * along;
        let side_sign = if n % 2 == 0 { 1.0 } else { -1.0 };
        let out = Vector3::new(rng.jitter(0.5), side_sign, rng.range(-0.2, 0.4)).normalize();
        let petiole = s.canopy_spread * rng.range(0.3, 1.0);
        let anchor = at + out * petiole;
        let droop = Vector3::new(rng.jitter(0.6), out.y * 0.4, rng.range(-1.0, 0.2)).normalize();
        let side = droop
            .cross(&Vector3::new(rng.jitter(0.3), rng.jitter(0.3), 1.0))
            .try_normalize(1e-6);
        let side = side.unwrap_or_else(Vector3::x);
        leaf(
            mesh,
            anchor,
            droop,
            side,
            s.leaf_size * rng.range(0.7, 1.15),
            rng.range(0.1, 0.4),
        );
    }
    // Lateral shoots' small leaves fill the canopy from stage 2.5 on.
    if s.laterals {
        let nodes = nodes as f64;
        let laterals =
            (s.lateral_ramp * nodes * 0.6 + s.extra_laterals_per_node * nodes).round() as usize;
        for _ in 0..laterals {
            let at = base + lean * (length * rng.range(0.15, 0.95));
            let out = Vector3::new(rng.jitter(1.0), rng.jitter(1.0), rng.jitter(0.5)).normalize();
            let anchor = at + out * (s.canopy_spread * rng.range(0.2, 1.0));
            let dir =
                Vector3::new(rng.jitter(1.0), rng.jitter(1.0), rng.range(-1.0, 0.3)).normalize();
            let side = dir
                .cross(&out)
                .try_normalize(1e-6)
                .unwrap_or_else(Vector3::y);
            leaf(
                mesh,
                anchor,
                dir,
                side,
                s.lateral_size * s.leaf_size * rng.range(0.7, 1.1),
                0.2,
            );
        }
    }
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

    /// Share of horizontal lines of sight across the row (perpendicular to it, through the
    /// middle plant of five in a row, heights 1.0-1.8 m: the leaf wall between the wires)
    /// that pass through the canopy without hitting anything.
    fn gap_fraction(g: f64, variation: f64) -> f64 {
        use crate::raycast::{Bvh, RayCaster};
        let mut row = Mesh::new();
        for i in 0..5 {
            let own = stream(2, &format!("own/{i}"));
            let mut rng = PlantRng::new(stream(2, "clone"), own, variation);
            let mut plant = vine(&layout(g), &mut rng);
            let dx = Vector3::new(i as f32 - 2.0, 0.0, 0.0);
            plant.vertices.iter_mut().for_each(|p| *p += dx);
            row.append(&plant);
        }
        let bvh = Bvh::build(&row);
        let (mut rays, mut gaps) = (0usize, 0usize);
        for ix in 0..100 {
            for iz in 0..80 {
                let x = -0.5 + (ix as f32 + 0.5) / 100.0;
                let z = 1.0 + (iz as f32 + 0.5) / 100.0;
                let origin = Point3::new(x, -1.5, z);
                rays += 1;
                if bvh.cast(&origin, &Vector3::y(), 0.0, 3.0).is_none() {
                    gaps += 1;
                }
            }
        }
        gaps as f64 / rays as f64
    }

    #[test]
    fn full_canopy_is_a_closed_leaf_wall() {
        // Before: the stage-4 canopy let the sky through (a sparse screen of single leaves),
        // where a vertically shoot-positioned vineyard at full growth is a closed wall.
        let gaps: Vec<f64> = [2.0, 3.0, 4.0]
            .iter()
            .map(|&g| gap_fraction(g, 0.0))
            .collect();
        let varied = gap_fraction(4.0, 1.0);
        eprintln!(
            "gap fraction at stages 2, 3, 4: {gaps:?}, stage 4 varied: {varied}; triangles \
             per plant at stage 3: {}, 4: {}",
            build(3.0).triangle_count(),
            build(4.0).triangle_count()
        );
        assert!(
            gaps[0] > gaps[1] && gaps[1] > gaps[2],
            "expected the canopy to close with stage: {gaps:?}"
        );
        for (what, gap) in [("clones", gaps[2]), ("varied plants", varied)] {
            assert!(
                gap < 0.12,
                "expected under 12 % gaps in the full canopy of {what}, got {gap}"
            );
        }
    }
}
