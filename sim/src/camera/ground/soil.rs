//! The soil patch: tilled ground with its lumps (`lumps`), then stones and plant debris
//! (`debris`); the crevices between lumps darkened, which also stands for the moister soil
//! down there.

use rayon::prelude::*;

use super::tile::{Texel, Tile};
use super::{SIDE, debris, lumps};

pub(super) fn generate() -> Tile {
    let mut texels: Vec<Texel> = (0..SIDE * SIDE)
        .into_par_iter()
        .with_min_len(SIDE)
        .map(|k| lumps::ground(k % SIDE, k / SIDE))
        .collect();
    lumps::lay(&mut texels);
    debris::scatter(&mut texels);
    Tile::finish(&texels, 0.18, 0.2, 1.15)
}
