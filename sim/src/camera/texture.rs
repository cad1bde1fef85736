//! Procedural materials: albedo (sRGB, 0..1) of a surface point from its texture-space
//! position. Value noise on an integer lattice hash (cheap, deterministic, no tables);
//! patterns sized for a 640x480 camera a metre or a few from the canopy. The ground (soil
//! and grass) is looked up in precomputed textures instead (`ground`).

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
}

/// What the materials need from a triangle that does not change across it, computed once
/// per world: for a leaf, which corner is the tip and the leaf's tone.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct TriConstants {
    /// The leaf's tip corner (1 or 2; the other is its side corner).
    pub tip: u8,
    /// One tone per leaf in [0, 1), from its petiole end's plant-local position.
    pub tone: f32,
}

impl TriConstants {
    /// From a triangle's material and corners in texture space.
    pub fn new(material: Material, corners: &[[f32; 3]; 3]) -> Self {
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
        Self {
            tip: if d(1) > d(2) { 1 } else { 2 },
            tone: hash(c0[0], c0[1], c0[2], 41),
        }
    }
}

/// Weight of a noise octave of wavelength `period_m` at `per_m` pixel footprints per metre:
/// 1 when resolved, fading to 0 (the octave's mean) below ~2 pixels per period.
fn octave(period_m: f32, per_m: f32) -> f32 {
    ((period_m * per_m - 2.0) * 0.5).clamp(0.0, 1.0)
}

/// A surface point's albedo (sRGB) and relief: the factor on direct sunlight from the
/// surface's small-scale shape (1 but for the ground, see [`GroundTexture`]).
pub(crate) fn albedo(s: &Surface, ground: &GroundTexture) -> ([f32; 3], f32) {
    let c = match s.material {
        Material::Soil | Material::Grass => return ground.sample(s.material, s.t, s.per_m),
        Material::Bark => bark(s.t, s.per_m),
        Material::Leaf => leaf(s),
        Material::Grape => grape(s.t),
        Material::Post => post(s.t),
        Material::Wire => wire(s.t),
    };
    (c, 1.0)
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
    let (fx, fy) = (smooth(x - xf), smooth(y - yf));
    let a = lerp(hash(xi, yi, 0, salt), hash(xi + 1, yi, 0, salt), fx);
    let b = lerp(hash(xi, yi + 1, 0, salt), hash(xi + 1, yi + 1, 0, salt), fx);
    lerp(a, b, fy)
}

/// 3D value noise in [0, 1) at lattice spacing 1.
fn noise3(p: [f32; 3], salt: u32) -> f32 {
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

fn scale(c: [f32; 3], k: f32) -> [f32; 3] {
    c.map(|x| x * k)
}

fn mix(a: [f32; 3], b: [f32; 3], t: f32) -> [f32; 3] {
    [
        lerp(a[0], b[0], t),
        lerp(a[1], b[1], t),
        lerp(a[2], b[2], t),
    ]
}

/// Vine bark: grey-brown with long dark fissures along the wood (ridged noise stretched
/// along z for trunks, the furrows of cordons come out shorter) and lighter shreds.
fn bark(t: [f32; 3], per_m: f32) -> [f32; 3] {
    let n = noise3([t[0] * 80.0, t[1] * 80.0, t[2] * 9.0], 31);
    let ridge = (n - 0.5).abs();
    let mut c = scale([0.40, 0.32, 0.25], 0.8 + 0.5 * ridge);
    let w = octave(0.012, per_m);
    if ridge < 0.07 {
        c = scale(c, 1.0 - (0.55 - 7.0 * ridge) * w.max(0.4));
    }
    if ridge > 0.42 {
        c = mix(c, [0.56, 0.50, 0.43], (ridge - 0.42) * 8.0);
    }
    c
}

/// A vine leaf: green varying from leaf to leaf (a function of the plant-local position,
/// so clones match), a lighter midrib and palmate main veins, paler underside.
fn leaf(s: &Surface) -> [f32; 3] {
    let (tip, side) = if s.k.tip == 1 { (1, 2) } else { (2, 1) };
    let across = s.w[side];
    let along = s.w[tip] + 0.45 * s.w[side];
    // One tone per leaf, flecks on the blade.
    let tone = s.k.tone;
    let fleck = noise2(along * 14.0, across * 9.0 + tone * 50.0, 42);
    let mut c = mix([0.22, 0.40, 0.10], [0.42, 0.52, 0.16], tone);
    c = scale(c, 0.9 + 0.2 * fleck);
    // Veins: the midrib (across = 0) and two main veins each side spreading from the base.
    let angle = across / (along + 0.08);
    let vein = (angle - 0.55).abs().min((angle - 1.3).abs()) * (along + 0.1);
    if across < 0.035 {
        c = mix(c, [0.62, 0.70, 0.36], 0.75);
    } else if vein < 0.025 {
        c = mix(c, [0.55, 0.64, 0.30], 0.55);
    }
    // Margin: slightly darker, serrated by noise.
    if across + 0.9 * along > 0.95 + 0.05 * fleck {
        c = scale(c, 0.8);
    }
    if s.back {
        c = mix(c, [0.62, 0.66, 0.52], 0.35);
    }
    c
}

/// Distant trees above the horizon, seen in the unit direction `d` (world frame): their
/// crown line height (elevation sine) and colour, or `None` where there is sky.
pub(crate) fn tree_line(d: &[f32; 3]) -> Option<[f32; 3]> {
    if d[2] > 0.03 || d[2] < -0.05 {
        return None;
    }
    let h = (d[0] * d[0] + d[1] * d[1]).sqrt().max(1e-6);
    let (x, y) = (d[0] / h * 30.0, d[1] / h * 30.0);
    let crown = 0.006 + 0.012 * noise2(x, y, 81) + 0.008 * noise2(x * 5.0, y * 5.0, 82);
    if d[2] > crown {
        return None;
    }
    let leaf = noise2(x * 25.0, y * 25.0 + d[2] * 600.0, 83);
    Some(scale([0.30, 0.38, 0.30], 0.8 + 0.3 * leaf))
}

/// A bunch of dark purple berries with a whitish bloom; one berry per 1.6 cm cell.
fn grape(t: [f32; 3]) -> [f32; 3] {
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

/// Wooden posts (treated pine): grey-brown with grain along the post and cracks.
fn post(t: [f32; 3]) -> [f32; 3] {
    let grain = noise3([t[0] * 160.0, t[1] * 160.0, t[2] * 6.0], 61);
    let knots = noise3(t.map(|c| c * 12.0), 62);
    let mut c = scale([0.55, 0.50, 0.42], 0.82 + 0.25 * grain);
    if (grain - 0.5).abs() < 0.03 {
        c = scale(c, 0.6);
    }
    if knots > 0.8 {
        c = scale(c, 0.75);
    }
    c
}

/// Galvanised wire: light grey with a faint sheen variation.
fn wire(t: [f32; 3]) -> [f32; 3] {
    let n = noise3(t.map(|c| c * 5.0), 71);
    scale([0.72, 0.73, 0.75], 0.85 + 0.2 * n)
}
