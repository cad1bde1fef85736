//! Procedural materials: albedo of a surface point from its texture-space position. Value
//! noise on an integer lattice hash (cheap, deterministic, no tables); patterns sized for a
//! 640x480 camera a metre or a few from the canopy. The ground (soil and grass) is looked
//! up in precomputed mip-mapped textures instead (`ground`).
//!
//! Filtering (`filter_materials`): a pixel should show the mean of its footprint, and
//! detail finer than the footprint, point-sampled, only aliases (shimmer from frame to
//! frame). The plants' materials are band-limited to the footprint in the two standard
//! ways of procedural texturing (Ebert, Musgrave, Peachey, Perlin & Worley, "Texturing and
//! Modeling: A Procedural Approach", 3rd ed. 2003, ch. 2 "Antialiasing"):
//! frequency clamping of noise and analytic prefiltering of thin features (`prefilter`).

use super::ground::GroundTexture;
use crate::world::Material;

/// What the shader knows about a surface point.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Surface {
    pub material: Material,
    /// Texture-space position.
    pub t: [f32; 3],
    /// Barycentric weights of the triangle's corners.
    pub w: [f32; 3],
    /// Per-triangle constants of the material (see [`TriConstants`]).
    pub k: TriConstants,
    /// The camera sees the triangle's back face.
    pub back: bool,
    /// Inverse size of the pixel's footprint on the surface (footprints per metre): detail
    /// finer than about two footprints is left out (it would only alias).
    pub per_m: f32,
    /// Band-limit the materials to the footprint (see the module's doc).
    pub filtered: bool,
}

/// What the materials need from a triangle that does not change across it, computed once
/// per world: for a leaf, which corner is the tip, the leaf's tone and how fast its pattern's
/// coordinates change across the surface.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct TriConstants {
    /// The leaf's tip corner (1 or 2; the other is its side corner).
    pub tip: u8,
    /// One tone per leaf in [0, 1), from its petiole end's plant-local position.
    pub tone: f32,
    /// Gradient norms (per metre) of the leaf's `across`, `along` and margin coordinates
    /// (see [`leaf`]).
    pub per_m: [f32; 3],
}

impl TriConstants {
    /// From a triangle's material, corners in texture space and the gradients of its
    /// barycentric weights of corners 1 and 2 (per metre, in its plane).
    pub fn new(material: Material, corners: &[[f32; 3]; 3], g: &[[f32; 3]; 2]) -> Self {
        if material != Material::Leaf {
            return Self::default();
        }
        // Corner 0 is the petiole end; the tip is the corner farther from it, the other the
        // leaf's side corner (see `world::shapes::leaf`).
        let d = |k: usize| {
            let a = corners[0];
            let b = corners[k];
            (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)
        };
        let c0 = corners[0].map(|c| floor(c * 500.0).1);
        let tip = if d(1) > d(2) { 1 } else { 2 };
        let (g_tip, g_side) = (g[tip - 1], g[2 - tip]);
        let norm = |a: f32, b: f32| {
            let v = [0, 1, 2].map(|k| a * g_tip[k] + b * g_side[k]);
            (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
        };
        Self {
            tip: tip as u8,
            tone: hash(c0[0], c0[1], c0[2], 41),
            per_m: [
                norm(0.0, 1.0),
                norm(1.0, LEAF_ALONG_SIDE),
                norm(LEAF_MARGIN_ALONG, 1.0 + LEAF_MARGIN_ALONG * LEAF_ALONG_SIDE),
            ],
        }
    }
}

/// Weight of a noise octave of wavelength `period_m` at `per_m` pixel footprints per metre:
/// 1 when resolved, fading to 0 (the octave's mean) below ~2 pixels per period.
fn octave(period_m: f32, per_m: f32) -> f32 {
    ((period_m * per_m - 2.0) * 0.5).clamp(0.0, 1.0)
}

pub(super) fn sq(c: [f32; 3]) -> [f32; 3] {
    c.map(|x| x * x)
}

/// A surface point's albedo, linear (the materials' sRGB colours squared: gamma 2, as the
/// output is encoded), and relief: the factor on direct sunlight from the surface's
/// small-scale shape (1 but for the ground, see [`GroundTexture`]).
pub(crate) fn albedo(s: &Surface, ground: &GroundTexture) -> ([f32; 3], f32) {
    if s.filtered {
        return super::prefilter::albedo(s, ground);
    }
    let c = match s.material {
        Material::Soil | Material::Grass => {
            let (c, relief) = ground.sample(s.material, s.t, s.per_m);
            return (sq(c), relief);
        }
        Material::Bark => bark(s.t, s.per_m),
        Material::Leaf => leaf(s),
        Material::Grape => grape(s.t),
        Material::Post => post(s.t),
        Material::Wire => wire(s.t),
    };
    (sq(c), 1.0)
}

pub(super) fn hash(x: i32, y: i32, z: i32, salt: u32) -> f32 {
    // Lattice hash: odd multipliers per axis, one multiply-xorshift finaliser.
    let mut h = (x as u32).wrapping_mul(0x8da6_b343)
        ^ (y as u32).wrapping_mul(0xd816_3841)
        ^ (z as u32).wrapping_mul(0xcb1a_b31f)
        ^ salt.wrapping_mul(0x9e37_79b9);
    h ^= h >> 15;
    h = h.wrapping_mul(0x2c1b_3c6d);
    h ^= h >> 13;
    (h >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// `x.floor()` without a libm call (baseline x86-64 has no SSE4.1 `roundps`), as f32 and i32.
pub(super) fn floor(x: f32) -> (f32, i32) {
    let i = x as i32;
    let i = if (i as f32) > x { i - 1 } else { i };
    (i as f32, i)
}

pub(super) fn smooth(f: f32) -> f32 {
    f * f * (3.0 - 2.0 * f)
}

pub(super) fn lerp(a: f32, b: f32, t: f32) -> f32 {
    a + (b - a) * t
}

/// 2D value noise in [0, 1) at lattice spacing 1.
pub(super) fn noise2(x: f32, y: f32, salt: u32) -> f32 {
    let ((xf, xi), (yf, yi)) = (floor(x), floor(y));
    noise2_in(cell2(xi, yi, salt), x - xf, y - yf)
}

/// The lattice values at the corners of cell `(xi, yi)`: `(xi, yi)`, `(xi + 1, yi)`,
/// `(xi, yi + 1)`, `(xi + 1, yi + 1)`.
fn cell2(xi: i32, yi: i32, salt: u32) -> [f32; 4] {
    [
        hash(xi, yi, 0, salt),
        hash(xi + 1, yi, 0, salt),
        hash(xi, yi + 1, 0, salt),
        hash(xi + 1, yi + 1, 0, salt),
    ]
}

/// [`noise2`] in a cell of lattice values `c` ([`cell2`]) at `(fx, fy)` from its corner.
#[inline(always)]
fn noise2_in(c: [f32; 4], fx: f32, fy: f32) -> f32 {
    let (fx, fy) = (smooth(fx), smooth(fy));
    let a = lerp(c[0], c[1], fx);
    let b = lerp(c[2], c[3], fx);
    lerp(a, b, fy)
}

/// [`noise2`] of one salt with the lattice values of the cells `[-HALF, HALF)^2` looked up
/// instead of hashed (the same values; the hash outside). For noise evaluated at every
/// pixel of a large surface, such as the ground's tone: its four hashes were a third of the
/// ground's lookup.
#[derive(Debug, Clone)]
pub(super) struct Noise2Table {
    salt: u32,
    cells: Vec<[f32; 4]>,
}

impl Noise2Table {
    const HALF: i32 = 64;

    pub fn new(salt: u32) -> Self {
        let side = 2 * Self::HALF;
        let cells = (0..side * side)
            .map(|k| cell2(k % side - Self::HALF, k / side - Self::HALF, salt))
            .collect();
        Self { salt, cells }
    }

    /// `noise2(x, y, salt)`, bit for bit.
    pub fn at(&self, x: f32, y: f32) -> f32 {
        let ((xf, xi), (yf, yi)) = (floor(x), floor(y));
        let (i, j) = (xi + Self::HALF, yi + Self::HALF);
        let side = 2 * Self::HALF;
        let c = if (0..side).contains(&i) && (0..side).contains(&j) {
            self.cells[(j * side + i) as usize]
        } else {
            cell2(xi, yi, self.salt)
        };
        noise2_in(c, x - xf, y - yf)
    }
}

/// 3D value noise in [0, 1) at lattice spacing 1.
pub(super) fn noise3(p: [f32; 3], salt: u32) -> f32 {
    let fl = p.map(floor);
    let f = fl.map(|c| c.0);
    let i = fl.map(|c| c.1);
    let s = [
        smooth(p[0] - f[0]),
        smooth(p[1] - f[1]),
        smooth(p[2] - f[2]),
    ];
    let plane = |dz: i32| {
        let a = lerp(
            hash(i[0], i[1], i[2] + dz, salt),
            hash(i[0] + 1, i[1], i[2] + dz, salt),
            s[0],
        );
        let b = lerp(
            hash(i[0], i[1] + 1, i[2] + dz, salt),
            hash(i[0] + 1, i[1] + 1, i[2] + dz, salt),
            s[0],
        );
        lerp(a, b, s[1])
    };
    lerp(plane(0), plane(1), s[2])
}

pub(super) fn scale(c: [f32; 3], k: f32) -> [f32; 3] {
    c.map(|x| x * k)
}

pub(super) fn mix(a: [f32; 3], b: [f32; 3], t: f32) -> [f32; 3] {
    [
        lerp(a[0], b[0], t),
        lerp(a[1], b[1], t),
        lerp(a[2], b[2], t),
    ]
}

/// Vine bark's ridged noise at `t`: lattice cells of 1/80 m across the wood and 1/9 m
/// along it (trunks stand along z; the furrows of cordons come out shorter).
pub(super) fn bark_ridge(t: [f32; 3]) -> f32 {
    let n = noise3([t[0] * 80.0, t[1] * 80.0, t[2] * 9.0], 31);
    (n - 0.5).abs()
}

/// Bark's colour (sRGB) at `ridge`, its fissures darkened by `fissure` (0..1).
pub(super) fn bark_colour(ridge: f32, fissure: f32) -> [f32; 3] {
    let mut c = scale([0.40, 0.32, 0.25], 0.8 + 0.5 * ridge);
    if ridge < 0.07 {
        c = scale(c, 1.0 - (0.55 - 7.0 * ridge) * fissure);
    }
    if ridge > 0.42 {
        c = mix(c, [0.56, 0.50, 0.43], (ridge - 0.42) * 8.0);
    }
    c
}

/// Vine bark: grey-brown with long dark fissures along the wood and lighter shreds.
fn bark(t: [f32; 3], per_m: f32) -> [f32; 3] {
    bark_colour(bark_ridge(t), octave(0.012, per_m).max(0.4))
}

/// A leaf's `along` coordinate is `w[tip] + LEAF_ALONG_SIDE * w[side]`.
pub(super) const LEAF_ALONG_SIDE: f32 = 0.45;
/// The margin lies where `across + LEAF_MARGIN_ALONG * along` exceeds about 0.95.
pub(super) const LEAF_MARGIN_ALONG: f32 = 0.9;
/// Half-widths of the midrib (in `across`) and of the main veins (in [`LeafCoords::vein`]).
pub(super) const MIDRIB_HALF_WIDTH: f32 = 0.035;
pub(super) const VEIN_HALF_WIDTH: f32 = 0.025;

/// Where a point lies on a leaf: across the blade from the midrib and along it from the
/// petiole end (barycentric units), and the leaf's flecks there.
#[derive(Debug, Clone, Copy)]
pub(super) struct LeafCoords {
    pub across: f32,
    pub along: f32,
}

impl LeafCoords {
    pub fn new(s: &Surface) -> Self {
        let (tip, side) = if s.k.tip == 1 { (1, 2) } else { (2, 1) };
        Self {
            across: s.w[side],
            along: s.w[tip] + LEAF_ALONG_SIDE * s.w[side],
        }
    }

    /// The flecks' value noise, lattice cells `1 / 14` along and `1 / 9` across.
    pub fn fleck(&self, tone: f32) -> f32 {
        noise2(self.along * 14.0, self.across * 9.0 + tone * 50.0, 42)
    }

    /// Distance (about, in `across` units) from the nearer of the two main veins each side,
    /// which spread from the base.
    pub fn vein(&self) -> f32 {
        let angle = self.across / (self.along + 0.08);
        (angle - 0.55).abs().min((angle - 1.3).abs()) * (self.along + 0.1)
    }

    /// Positive on the margin (serrated by the flecks).
    pub fn margin(&self, fleck: f32) -> f32 {
        self.across + LEAF_MARGIN_ALONG * self.along - (0.95 + 0.05 * fleck)
    }
}

/// The leaf's blade colour (sRGB) for its tone and flecks.
pub(super) fn leaf_blade(tone: f32, fleck: f32) -> [f32; 3] {
    scale(
        mix([0.22, 0.40, 0.10], [0.42, 0.52, 0.16], tone),
        0.9 + 0.2 * fleck,
    )
}

pub(super) fn leaf_midrib(blade: [f32; 3]) -> [f32; 3] {
    mix(blade, [0.62, 0.70, 0.36], 0.75)
}

pub(super) fn leaf_vein(blade: [f32; 3]) -> [f32; 3] {
    mix(blade, [0.55, 0.64, 0.30], 0.55)
}

/// The margin is slightly darker, the underside paler.
pub(super) fn leaf_finish(c: [f32; 3], margin: bool, back: bool) -> [f32; 3] {
    let c = if margin { scale(c, 0.8) } else { c };
    if back {
        mix(c, [0.62, 0.66, 0.52], 0.35)
    } else {
        c
    }
}

/// A vine leaf: green varying from leaf to leaf (a function of the plant-local position,
/// so clones match), a lighter midrib and palmate main veins, paler underside.
fn leaf(s: &Surface) -> [f32; 3] {
    let p = LeafCoords::new(s);
    // One tone per leaf, flecks on the blade.
    let fleck = p.fleck(s.k.tone);
    let blade = leaf_blade(s.k.tone, fleck);
    // Veins: the midrib (across = 0) and two main veins each side spreading from the base.
    let c = if p.across < MIDRIB_HALF_WIDTH {
        leaf_midrib(blade)
    } else if p.vein() < VEIN_HALF_WIDTH {
        leaf_vein(blade)
    } else {
        blade
    };
    // Margin: slightly darker, serrated by noise.
    leaf_finish(c, p.margin(fleck) > 0.0, s.back)
}

/// Distant trees above the horizon, seen in the unit direction `d` (world frame): their
/// colour (sRGB), or `None` where there is sky.
pub(crate) fn tree_line(d: &[f32; 3]) -> Option<[f32; 3]> {
    let (x, y, crown) = tree_crown(d)?;
    if d[2] > crown {
        return None;
    }
    let leaf = noise2(x * 25.0, y * 25.0 + d[2] * 600.0, 83);
    Some(tree_colour(leaf))
}

/// Above this elevation sine no distant tree reaches: sky only.
pub(super) const TREE_LINE_TOP: f32 = 0.03;

/// The tree line's coordinates `(x, y)` in the direction `d` (30 per radian of azimuth)
/// and its crown height (elevation sine) there; `None` far from the horizon.
pub(super) fn tree_crown(d: &[f32; 3]) -> Option<(f32, f32, f32)> {
    if d[2] > TREE_LINE_TOP || d[2] < -0.05 {
        return None;
    }
    let h = (d[0] * d[0] + d[1] * d[1]).sqrt().max(1e-6);
    let (x, y) = (d[0] / h * 30.0, d[1] / h * 30.0);
    let crown = 0.006 + 0.012 * noise2(x, y, 81) + 0.008 * noise2(x * 5.0, y * 5.0, 82);
    Some((x, y, crown))
}

/// The trees' colour (sRGB) at their foliage noise `leaf`.
pub(super) fn tree_colour(leaf: f32) -> [f32; 3] {
    scale([0.30, 0.38, 0.30], 0.8 + 0.3 * leaf)
}

/// A bunch of dark purple berries with a whitish bloom; one berry per 1.6 cm cell.
pub(super) fn grape(t: [f32; 3]) -> [f32; 3] {
    let g = t.map(|c| c / 0.016);
    let fl = g.map(floor);
    let f = fl.map(|c| c.0);
    let i = fl.map(|c| c.1);
    let r2: f32 = (0..3).map(|k| (g[k] - f[k] - 0.5).powi(2)).sum::<f32>();
    let tone = hash(i[0], i[1], i[2], 51);
    let base = mix([0.16, 0.08, 0.18], [0.28, 0.14, 0.26], tone);
    let shade = (1.0 - 1.6 * r2).max(0.25);
    let bloom = (1.0 - 4.0 * r2).max(0.0) * 0.12;
    [
        base[0] * shade + bloom,
        base[1] * shade + bloom,
        base[2] * shade + 1.3 * bloom,
    ]
}

/// Post colour (sRGB) before grain and knots.
pub(super) const POST_BASE: [f32; 3] = [0.55, 0.50, 0.42];

/// A post's grain (lattice cells 1/160 m across, 1/6 m along the post) and knots (1/12 m).
pub(super) fn post_grain(t: [f32; 3]) -> f32 {
    noise3([t[0] * 160.0, t[1] * 160.0, t[2] * 6.0], 61)
}

pub(super) fn post_knots(t: [f32; 3]) -> f32 {
    noise3(t.map(|c| c * 12.0), 62)
}

/// Wooden posts (treated pine): grey-brown with grain along the post, cracks along the
/// grain (where it is near 0.5) and knots (where their noise exceeds 0.8).
fn post(t: [f32; 3]) -> [f32; 3] {
    let grain = post_grain(t);
    let knots = post_knots(t);
    let mut c = scale(POST_BASE, 0.82 + 0.25 * grain);
    if (grain - 0.5).abs() < 0.03 {
        c = scale(c, 0.6);
    }
    if knots > 0.8 {
        c = scale(c, 0.75);
    }
    c
}

/// Galvanised wire: light grey with a faint sheen variation (20 cm cells: nothing to
/// filter).
pub(super) fn wire(t: [f32; 3]) -> [f32; 3] {
    let n = noise3(t.map(|c| c * 5.0), 71);
    scale([0.72, 0.73, 0.75], 0.85 + 0.2 * n)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// The table gives `noise2`'s bits inside its cells, on their edges and beyond them.
    #[test]
    fn tabled_noise_is_the_hashed_noise() {
        let table = Noise2Table::new(1);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2);
        let edge = Noise2Table::HALF as f32;
        let mut points: Vec<(f32, f32)> = (0..50_000)
            .map(|_| {
                (
                    rng.random_range(-1.5 * edge..1.5 * edge),
                    rng.random_range(-1.5 * edge..1.5 * edge),
                )
            })
            .collect();
        points.extend([
            (-edge, -edge),
            (edge - 1e-3, edge - 1e-3),
            (edge, 0.0),
            (0.0, -edge - 1e-3),
            (3.0, -7.0),
        ]);
        for (x, y) in points {
            assert_eq!(
                table.at(x, y).to_bits(),
                noise2(x, y, 1).to_bits(),
                "at ({x}, {y})"
            );
        }
    }
}
