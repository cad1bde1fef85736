//! The ground's textures: tileable patches of tilled vineyard soil (`soil`) and of headland
//! grass (`grass`), each generated once as a height field and an albedo, lit by the
//! camera's sun once per camera and kept as a mip map (`mips`).
//!
//! A texel holds the albedo and a relief factor: the direct sunlight its small-scale shape
//! receives relative to a flat surface (`relief`). The shader multiplies direct sun by it,
//! so clods, stones and tufts cast short shadows in the sun and the relief fades, as it
//! should, in a vine's shadow. The patches are laid in the world at an angle to the rows
//! and tinted by world-space noise (moist and dry patches over metres), which does not
//! repeat, so their period is hard to see. Generated from fixed hashes, they are the same
//! in every world, as the rest of the materials are.

mod debris;
mod grass;
mod grid;
mod lumps;
mod mips;
mod relief;
mod soil;
mod tile;

use std::sync::OnceLock;

use super::shading::Light;
use super::texture::Noise2Table;
use crate::world::Material;
use mips::Mips;
use relief::relief;
use tile::Tile;

/// Texels along each side of a patch (a power of two, for the mip chain and wrapping).
const SIDE: usize = 1024;
/// Soil texel, metres: about a pixel's footprint on the ground 1.3 m ahead of the camera.
const SOIL_TEXEL_M: f32 = 0.004;
/// Grass texel, metres (grass is mostly seen from afar).
const GRASS_TEXEL_M: f32 = 0.006;
/// The patches' x axis in the world frame: about 37° from the rows.
const AXIS: [f32; 2] = [0.8, 0.6];
/// Largest relief factor kept (a slope facing a low sun).
const MAX_RELIEF: f32 = 2.0;
/// Mip levels sharper than the pixel footprint: the footprint is the geometric mean of its
/// axes, and half a level more keeps the detail a camera resolves at grazing angles.
const LOD_BIAS: f32 = 0.5;

#[derive(Debug, Clone)]
pub(crate) struct GroundTexture {
    soil: Mips,
    grass: Mips,
    /// The tone's noise (see [`tone_noise`]).
    tone: &'static Noise2Table,
}

/// The soil and grass patches, generated once per process: they depend on constants only.
fn tiles() -> &'static (Tile, Tile) {
    static TILES: OnceLock<(Tile, Tile)> = OnceLock::new();
    TILES.get_or_init(|| rayon::join(soil::generate, grass::generate))
}

/// The tone's noise (salt 1), tabulated over the lattice cells within about 90 m of the
/// origin (the vineyard and its surroundings), once per process.
fn tone_noise() -> &'static Noise2Table {
    static TONE: OnceLock<Noise2Table> = OnceLock::new();
    TONE.get_or_init(|| Noise2Table::new(1))
}

impl GroundTexture {
    pub fn new(light: &Light) -> Self {
        let (soil, grass) = tiles();
        let mips =
            |tile: &Tile, texel_m| Mips::new(&tile.albedo, &relief(&tile.height, light), texel_m);
        Self {
            soil: mips(soil, SOIL_TEXEL_M),
            grass: mips(grass, GRASS_TEXEL_M),
            tone: tone_noise(),
        }
    }

    /// The ground (soil or grass) at world position `t` seen with `per_m` pixel footprints
    /// per metre: its albedo (sRGB) and relief factor.
    pub fn sample(&self, material: Material, t: [f32; 3], per_m: f32) -> ([f32; 3], f32) {
        let (x, y) = (t[0], t[1]);
        let (u, v) = (AXIS[0] * x + AXIS[1] * y, AXIS[0] * y - AXIS[1] * x);
        let mips = if material == Material::Grass {
            &self.grass
        } else {
            &self.soil
        };
        let (c, relief) = mips.sample(u, v, per_m, LOD_BIAS);
        // Moist and dry patches over metres.
        let tone = 0.88 + 0.24 * self.tone.at(x * 0.7, y * 0.7);
        (c.map(|c| c * tone), relief)
    }
}
