//! The procedural materials band-limited to the pixel footprint (`filter_materials`).
//!
//! A pixel should show the mean of the surface in its footprint; detail finer than the
//! footprint, point-sampled, only aliases (it shimmers from frame to frame and makes corners
//! that are not on the surface). The standard remedies of procedural texturing (Ebert,
//! Musgrave, Peachey, Perlin & Worley, "Texturing and Modeling: A Procedural Approach",
//! 3rd ed. 2003, ch. 2, "Antialiasing" and "clamping"), both used here:
//! - frequency clamping: a noise pattern fades to its mean as its lattice cell shrinks from
//!   two pixel footprints to one ([`fade`]; value noise has little energy above one cycle
//!   per two cells). The means are measured once from the patterns themselves ([`Means`]),
//!   in linear light, where the pixel averages, so fading keeps a surface's brightness;
//! - analytic prefiltering: a thin stripe or a step of the pattern is replaced by the
//!   fraction of the footprint it covers (a box filter, exact: [`stripe`], [`step`]), with
//!   the footprint measured in the pattern's own coordinates (for a leaf, its barycentric
//!   coordinates, whose gradients are constant over the triangle; for a threshold on noise,
//!   the noise's mean slope).
//!
//! The footprint is the geometric mean of its axes (as the ground's mip level): detail
//! along a surface seen at a grazing angle fades a little early across the line of sight and
//! a little late along it. Everything here returns linear albedo (the sRGB colours of
//! `texture` squared: gamma 2, as the output is encoded).

use std::sync::OnceLock;

use super::ground::GroundTexture;
use super::texture::{
    LeafCoords, MIDRIB_HALF_WIDTH, POST_BASE, Surface, VEIN_HALF_WIDTH, bark_colour, bark_ridge,
    grape, leaf_blade, leaf_finish, leaf_midrib, leaf_vein, lerp, noise2, noise3, post_grain,
    post_knots, sq, tree_colour, tree_crown, wire,
};
use crate::world::Material;

/// Bark's lattice cell across the wood (its finest), metres.
const BARK_CELL_M: f32 = 1.0 / 80.0;
/// A berry's bloom and shading vary over half its 1.6 cm cell.
const GRAPE_DETAIL_M: f32 = 0.008;
/// A post's grain cell across the wood and its knots' cell, metres.
const GRAIN_CELL_M: f32 = 1.0 / 160.0;
const KNOT_CELL_M: f32 = 1.0 / 12.0;
/// The leaf's flecks: lattice cells in its `along` and `across` coordinates.
const FLECK_CELL_ALONG: f32 = 1.0 / 14.0;
const FLECK_CELL_ACROSS: f32 = 1.0 / 9.0;
/// The distant trees' foliage noise: lattice cell in radians of azimuth.
const TREE_LEAF_CELL_RAD: f32 = 1.0 / (30.0 * 25.0);

/// Weight of a pattern of lattice cell `cell` (any unit) seen with footprints of `footprint`
/// (the same unit): 1 while a cell spans two footprints or more, fading linearly to 0 (the
/// pattern's mean) at one footprint a cell.
fn fade(cell: f32, footprint: f32) -> f32 {
    (cell / footprint - 1.0).clamp(0.0, 1.0)
}

/// The fraction of a footprint `f` wide (in the units of `x`), centred on `x`, that lies in
/// the stripe `|x| < half_width`: the stripe box-filtered, exactly.
pub(super) fn stripe(x: f32, half_width: f32, f: f32) -> f32 {
    let x = x.abs();
    if f <= 2.0 * half_width {
        // The footprint meets at most the nearer edge: a ramp across it (the form that
        // stays exact as `f` vanishes).
        ((half_width - x) / f.max(1e-9) + 0.5).clamp(0.0, 1.0)
    } else {
        let h = 0.5 * f;
        ((x + h).min(half_width) - (x - h).max(-half_width)).max(0.0) / f
    }
}

/// The fraction of a footprint `f` wide centred on `x` where `x > 0`: a box-filtered step.
pub(super) fn step(x: f32, f: f32) -> f32 {
    (x / f.max(1e-9) + 0.5).clamp(0.0, 1.0)
}

/// Means of the patterns in linear light, measured once per process over 2^16 points of a
/// quasi-random sequence (the R3 sequence: Roberts 2018, "The unreasonable effectiveness
/// of quasirandom sequences") spread over a metre-wide cube of texture space.
#[derive(Debug, Clone, Copy)]
pub(super) struct Means {
    pub bark: [f32; 3],
    pub grape: [f32; 3],
    /// A post's grain factor squared, `((0.82 + 0.25 g) (0.6 on a crack))^2`.
    pub post_grain: f32,
    /// A post's knot factor squared (0.75 on a knot).
    pub post_knots: f32,
    /// Mean absolute slope of 3D value noise along one lattice axis, per cell.
    pub noise_slope: f32,
}

pub(super) fn means() -> &'static Means {
    static MEANS: OnceLock<Means> = OnceLock::new();
    MEANS.get_or_init(|| {
        const N: usize = 1 << 16;
        // 1 / φ3^k for the plastic number's analogue φ3 = 1.2207440846 (Roberts 2018).
        let g = 1.220_744_1_f64;
        let alpha = [1.0 / g, 1.0 / (g * g), 1.0 / (g * g * g)];
        let (mut bark, mut grape_sum) = ([0.0f64; 3], [0.0f64; 3]);
        let (mut grain, mut knots, mut slope) = (0.0f64, 0.0f64, 0.0f64);
        for n in 0..N {
            let t = alpha.map(|a| ((0.5 + a * n as f64).fract()) as f32);
            let b = sq(bark_colour(bark_ridge(t), 1.0));
            let c = sq(grape(t));
            for k in 0..3 {
                bark[k] += f64::from(b[k]);
                grape_sum[k] += f64::from(c[k]);
            }
            let gr = post_grain(t);
            let crack = if (gr - 0.5).abs() < 0.03 { 0.36 } else { 1.0 };
            grain += f64::from((0.82 + 0.25 * gr).powi(2) * crack);
            knots += if post_knots(t) > 0.8 { 0.5625 } else { 1.0 };
            // Over 64 cells a side, a central difference of 1/1000 of a cell.
            let p = t.map(|x| x * 64.0);
            let h = 1e-3;
            let d = noise3([p[0] + h, p[1], p[2]], 7) - noise3([p[0] - h, p[1], p[2]], 7);
            slope += f64::from(d.abs() / (2.0 * h));
        }
        let mean = |s: f64| (s / N as f64) as f32;
        Means {
            bark: bark.map(mean),
            grape: grape_sum.map(mean),
            post_grain: mean(grain),
            post_knots: mean(knots),
            noise_slope: mean(slope),
        }
    })
}

fn lerp3(a: [f32; 3], b: [f32; 3], t: f32) -> [f32; 3] {
    [0, 1, 2].map(|k| lerp(a[k], b[k], t))
}

/// [`super::texture::albedo`], band-limited: linear albedo and relief.
pub(super) fn albedo(s: &Surface, ground: &GroundTexture) -> ([f32; 3], f32) {
    let footprint_m = 1.0 / s.per_m;
    let m = means();
    let c = match s.material {
        Material::Soil | Material::Grass => {
            let (c, relief) = ground.sample(s.material, s.t, s.per_m);
            return (sq(c), relief);
        }
        Material::Bark => {
            let w = fade(BARK_CELL_M, footprint_m);
            if w > 0.0 {
                lerp3(m.bark, sq(bark_colour(bark_ridge(s.t), 1.0)), w)
            } else {
                m.bark
            }
        }
        Material::Grape => {
            let w = fade(GRAPE_DETAIL_M, footprint_m);
            if w > 0.0 {
                lerp3(m.grape, sq(grape(s.t)), w)
            } else {
                m.grape
            }
        }
        Material::Post => post(s.t, footprint_m, m),
        Material::Leaf => leaf(s, footprint_m),
        Material::Wire => sq(wire(s.t)),
    };
    (c, 1.0)
}

/// The post's grain with its cracks (a stripe of the grain's value) and its knots (a step
/// of theirs), each box-filtered with the noise's mean slope, then faded to its mean.
fn post(t: [f32; 3], footprint_m: f32, m: &Means) -> [f32; 3] {
    let w_grain = fade(GRAIN_CELL_M, footprint_m);
    let grain = if w_grain > 0.0 {
        let g = post_grain(t);
        let f = m.noise_slope * footprint_m / GRAIN_CELL_M;
        let crack = stripe(g - 0.5, 0.03, f);
        let detail = (0.82 + 0.25 * g).powi(2) * (1.0 - 0.64 * crack);
        lerp(m.post_grain, detail, w_grain)
    } else {
        m.post_grain
    };
    let w_knots = fade(KNOT_CELL_M, footprint_m);
    let knots = if w_knots > 0.0 {
        let k = post_knots(t);
        let f = m.noise_slope * footprint_m / KNOT_CELL_M;
        let detail = 1.0 - 0.4375 * step(k - 0.8, f);
        lerp(m.post_knots, detail, w_knots)
    } else {
        m.post_knots
    };
    sq(POST_BASE).map(|c| c * grain * knots)
}

/// The leaf of `texture`, box-filtered: the midrib and main veins are stripes of the
/// leaf's `across` coordinate (about) and the margin a step, each covering a fraction of the
/// footprint; the flecks fade to their mean. The colour is the linear mix of the point
/// sampled leaf's colours over the regions the footprint covers.
fn leaf(s: &Surface, footprint_m: f32) -> [f32; 3] {
    let p = LeafCoords::new(s);
    // The footprint in the leaf's coordinates (each changes `per_m[k]` per metre).
    let [f_across, f_along, f_margin] = s.k.per_m.map(|g| g * footprint_m);
    let tone = s.k.tone;
    let w = fade(FLECK_CELL_ALONG, f_along).min(fade(FLECK_CELL_ACROSS, f_across));
    let fleck = if w > 0.0 {
        0.5 + (p.fleck(tone) - 0.5) * w
    } else {
        0.5
    };
    let blade = leaf_blade(tone, fleck);
    let midrib = stripe(p.across, MIDRIB_HALF_WIDTH, f_across);
    let vein = stripe(p.vein(), VEIN_HALF_WIDTH, f_across) * (1.0 - midrib);
    let margin = step(p.margin(fleck), f_margin);
    let mut out = [0.0f32; 3];
    for (colour, share) in [
        (blade, 1.0 - midrib - vein),
        (leaf_midrib(blade), midrib),
        (leaf_vein(blade), vein),
    ] {
        for (on_margin, part) in [(false, 1.0 - margin), (true, margin)] {
            let w = share * part;
            if w > 0.0 {
                let c = sq(leaf_finish(colour, on_margin, s.back));
                for (acc, c) in out.iter_mut().zip(c) {
                    *acc += c * w;
                }
            }
        }
    }
    out
}

/// Distant trees in the unit direction `d`, seen with a footprint of `footprint_rad`: their
/// colour (sRGB, the foliage noise faded to its mean as it gets finer than the footprint)
/// and the fraction of the footprint under their crown line (a box-filtered step); `None`
/// where they cover none of it.
pub(super) fn tree_line(d: &[f32; 3], footprint_rad: f32) -> Option<([f32; 3], f32)> {
    let (x, y, crown) = tree_crown(d)?;
    let cover = step(crown - d[2], footprint_rad);
    if cover <= 0.0 {
        return None;
    }
    let w = fade(TREE_LEAF_CELL_RAD, footprint_rad);
    let leaf = if w > 0.0 {
        0.5 + (noise2(x * 25.0, y * 25.0 + d[2] * 600.0, 83) - 0.5) * w
    } else {
        0.5
    };
    Some((tree_colour(leaf), cover))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_filters_are_exact_coverage() {
        // A stripe 0.2 wide, a footprint 0.1 wide: inside, outside, and straddling by a
        // quarter of the footprint.
        assert_eq!(stripe(0.0, 0.1, 0.1), 1.0);
        assert_eq!(stripe(0.3, 0.1, 0.1), 0.0);
        assert!((stripe(0.125, 0.1, 0.1) - 0.25).abs() < 1e-6);
        // A footprint wider than the stripe sees its width over the footprint's.
        assert!((stripe(0.0, 0.1, 1.0) - 0.2).abs() < 1e-6);
        // A vanishing footprint is the point sample.
        assert_eq!(stripe(0.09, 0.1, 0.0), 1.0);
        assert_eq!(stripe(0.11, 0.1, 0.0), 0.0);
        assert_eq!(step(0.0, 0.2), 0.5);
        assert!((step(0.05, 0.2) - 0.75).abs() < 1e-6);
        assert_eq!(step(0.2, 0.2), 1.0);
    }

    /// Band-limiting keeps each material's brightness: averaged over the surface, the
    /// filtered albedo equals the point-sampled one (in linear light) at every footprint,
    /// from full detail to the mean.
    #[test]
    fn fading_keeps_the_mean_albedo() {
        let ground = GroundTexture::new(&super::super::shading::Light::new(50.0, 30.0));
        let g = 1.220_744_1_f64;
        let alpha = [1.0 / g, 1.0 / (g * g), 1.0 / (g * g * g)];
        for material in [Material::Bark, Material::Grape, Material::Post] {
            let surface = |t: [f32; 3], per_m: f32, filtered: bool| Surface {
                material,
                t,
                w: [1.0, 0.0, 0.0],
                k: Default::default(),
                back: false,
                per_m,
                filtered,
            };
            let n = 40_000;
            // Points of another sequence than the means' (offset 0.25, a 2 m cube).
            let points: Vec<[f32; 3]> = (0..n)
                .map(|i| alpha.map(|a| (2.0 * (0.25 + a * i as f64).fract()) as f32))
                .collect();
            let mean = |per_m: f32, filtered: bool| {
                let mut sum = [0.0f64; 3];
                for &t in &points {
                    let (c, _) =
                        super::super::texture::albedo(&surface(t, per_m, filtered), &ground);
                    for k in 0..3 {
                        sum[k] += f64::from(c[k]);
                    }
                }
                sum.map(|s| s / n as f64)
            };
            let reference = mean(1e4, false);
            for per_m in [1e4, 200.0, 120.0, 80.0, 20.0] {
                let got = mean(per_m, true);
                for k in 0..3 {
                    assert!(
                        (got[k] / reference[k] - 1.0).abs() < 0.02,
                        "{material:?} at {per_m} footprints/m: mean channel {k} {} against the \
                         point-sampled {}",
                        got[k],
                        reference[k]
                    );
                }
            }
        }
    }
}
