//! A simulated vineyard route of binary descriptors, for `tests/all/bow.rs` and `benches/bow.rs`
//! (both include this file with `#[path]`, so it is built into neither the library nor any
//! test binary of its own).
//!
//! Landmarks come in families of four (a vineyard repeats itself: similar leaves, posts,
//! wires) whose members differ from a common random prototype by 12–24 bits, and an
//! observation is the landmark's descriptor with 0–10 bits flipped. Location `k` of a
//! [`Route`] sees `per_location` consecutive landmarks from `k * stride` on, so consecutive
//! locations share `per_location - stride` of them.

use std::ops::Range;

use rand::Rng;
use rand::seq::index::sample;
use rand_chacha::ChaCha8Rng;
use slam_common::place::bow::Descriptor;

/// `d` with `bits` distinct bits flipped.
pub fn flip(d: &Descriptor, bits: usize, rng: &mut ChaCha8Rng) -> Descriptor {
    let mut out = *d;
    for b in sample(rng, 256, bits) {
        out[b / 8] ^= 1 << (b % 8);
    }
    out
}

/// An observation of a landmark: 0–10 bits flipped.
pub fn observe(d: &Descriptor, rng: &mut ChaCha8Rng) -> Descriptor {
    let bits = rng.random_range(0..=10);
    flip(d, bits, rng)
}

/// Landmark descriptors: families of four around random prototypes.
pub fn landmarks(n: usize, rng: &mut ChaCha8Rng) -> Vec<Descriptor> {
    let mut out = Vec::with_capacity(n);
    while out.len() < n {
        let prototype: Descriptor = rng.random();
        for _ in 0..4 {
            let bits = rng.random_range(12..=24);
            out.push(flip(&prototype, bits, rng));
        }
    }
    out.truncate(n);
    out
}

/// How the landmarks of a world are laid out along the route.
#[derive(Debug, Clone, Copy)]
pub struct Route {
    /// Landmarks seen from every location.
    pub per_location: usize,
    /// Landmarks between the first ones of consecutive locations.
    pub stride: usize,
}

impl Route {
    /// The landmarks of locations `0..=last`.
    pub fn world(&self, last: usize, rng: &mut ChaCha8Rng) -> Vec<Descriptor> {
        landmarks(last * self.stride + self.per_location, rng)
    }

    /// Indices into the world of the landmarks seen from location `k`.
    pub fn seen(&self, k: usize) -> Range<usize> {
        k * self.stride..k * self.stride + self.per_location
    }

    /// An observation of each landmark seen from location `k`, in landmark order.
    pub fn location(
        &self,
        world: &[Descriptor],
        k: usize,
        rng: &mut ChaCha8Rng,
    ) -> Vec<Descriptor> {
        world[self.seen(k)]
            .iter()
            .map(|d| observe(d, rng))
            .collect()
    }
}
