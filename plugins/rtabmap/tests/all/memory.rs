//! Memory management under the comparison limit (`Rtabmap/TimeThr` counted): working memory
//! settles where quantising a location stays within the limit, and grows without it.
//!
//! The vocabulary as this plugin runs it (`slam_common::place::bow` at `word_probe_radius = 3`,
//! exact within 64 bits), where quantisation settles the descriptors still undecided after
//! the cheap probe radii by a linear scan: every word it gives is the one a brute-force
//! scan gives, on a simulated vineyard route (slam-common's `tests/support/bow_route.rs`)
//! after memory management has removed locations and left free slots in the index.

use crate::bow_route::{Route, flip, observe};
use nalgebra::Isometry3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rtabmap::config::{LoopClosureConfig, MemoryConfig};
use rtabmap::features::Features;
use rtabmap::memory::{Location, Memory, Update};
use slam_common::place::bow::{Descriptor, Dictionary, DictionaryConfig, SignatureId, hamming};

const ROUTE: Route = Route {
    per_location: 500,
    stride: 250,
};

/// The capped ratio test of `slam_common::place::bow` by brute force: the nearest word if it is
/// nearer than `nndr · min(second, R)`.
fn brute_force(dictionary: &Dictionary, q: &Descriptor) -> Option<u32> {
    let mut all: Vec<(u32, u32)> = dictionary
        .words()
        .map(|(word, d)| (hamming(q, d), word))
        .collect();
    all.sort_unstable();
    let radius = dictionary.search_radius();
    let nndr = dictionary.config().nndr;
    let (d1, w1) = *all.first()?;
    let d2 = all.get(1).map_or(u32::MAX, |m| m.0);
    ((d1 as f32) < nndr * d2.min(radius) as f32).then_some(w1)
}

#[test]
fn quantisation_by_scan_is_the_brute_force_result() {
    let defaults = MemoryConfig::default();
    let mut dictionary = Dictionary::new(DictionaryConfig {
        nndr: defaults.word_nndr,
        probe_radius: defaults.word_probe_radius,
    });
    assert_eq!(
        dictionary.search_radius(),
        64,
        "the plugin's default radius"
    );
    let mut rng = ChaCha8Rng::seed_from_u64(17);
    let locations = 80;
    let world = ROUTE.world(locations + 20, &mut rng);
    for k in 0..locations {
        dictionary.add_signature(k as SignatureId, &ROUTE.location(&world, k, &mut rng));
    }
    // The oldest half leaves working memory, as the memory limits do: their words' slots
    // are freed, then partly reused by the next locations.
    for k in 0..locations / 2 {
        dictionary.remove_signature(k as SignatureId);
    }
    for k in locations..locations + 5 {
        dictionary.add_signature(k as SignatureId, &ROUTE.location(&world, k, &mut rng));
    }
    let scan_from = dictionary.scan_from();
    println!(
        "{} words, scanning from probe radius {scan_from:?}",
        dictionary.word_count()
    );
    assert!(
        scan_from.is_some(),
        "at 64 bits the undecided descriptors are scanned"
    );

    // Re-observations of landmarks still held and of landmarks whose words left with their
    // locations (their stale descriptors lie in free slots, which must not match), hard
    // cases 11-45 bits from a landmark, and unrelated descriptors.
    let mut queries: Vec<(&str, Descriptor)> = Vec::new();
    for _ in 0..600 {
        let l = rng.random_range(0..world.len());
        queries.push(("observation", observe(&world[l], &mut rng)));
    }
    for _ in 0..300 {
        let l = rng.random_range(0..world.len());
        let bits = rng.random_range(11..=45);
        queries.push(("hard", flip(&world[l], bits, &mut rng)));
    }
    for _ in 0..100 {
        queries.push(("random", rng.random()));
    }
    let descriptors: Vec<Descriptor> = queries.iter().map(|q| q.1).collect();
    let quantised = dictionary.quantize(&descriptors);
    let mut matched = 0;
    for ((kind, q), word) in queries.iter().zip(&quantised) {
        assert_eq!(*word, brute_force(&dictionary, q), "{kind} query");
        matched += usize::from(word.is_some());
    }
    println!("{matched} of {} queries took a word", queries.len());
    assert!(
        matched > 300 && matched < 900,
        "both outcomes occur: {matched}"
    );
}

/// Drives `n` locations of the route through a memory with this comparison limit; returns
/// every update.
fn drive(comparison_limit: u64, n: usize) -> Vec<Update> {
    let cfg = MemoryConfig {
        comparison_limit,
        ..MemoryConfig::default()
    };
    let mut memory = Memory::new(&cfg, &LoopClosureConfig::default());
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let world = ROUTE.world(n, &mut rng);
    (0..n)
        .map(|k| {
            let descriptors = ROUTE.location(&world, k, &mut rng);
            let location = Location {
                id: k as u64,
                stamp_ns: k as i64 * 1_000_000_000,
                odom_from_base: Isometry3::identity(),
                features: Features {
                    pixels: vec![[0.0, 0.0]; descriptors.len()],
                    points: vec![None; descriptors.len()],
                    descriptors,
                },
                words: Vec::new(),
                scan: None,
                cloud: Vec::new(),
            };
            memory.add(location, true).2
        })
        .collect()
}

#[test]
fn the_comparison_limit_bounds_working_memory() {
    let n = 120;
    let unlimited = drive(0, n);
    let stm = MemoryConfig::default().short_term_memory;
    assert!(unlimited.iter().all(|u| u.transferred == 0));
    assert_eq!(unlimited.last().map(|u| u.working_memory), Some(n - stm));
    let last = unlimited.last().expect("updates");
    println!(
        "unlimited: {} words, {} comparisons at the last location",
        last.vocabulary_words, last.comparisons
    );

    // 20 locations' worth of words: 500 descriptors against ~5000 words.
    let limit = 2_500_000;
    let limited = drive(limit, n);
    for (k, (u, v)) in limited.iter().zip(&unlimited).enumerate() {
        // Each update over the limit sends the two oldest WM locations to LTM (when WM
        // holds two), and nothing else does.
        let expected = if u.comparisons > limit {
            2.min(u.working_memory + u.transferred)
        } else {
            0
        };
        assert_eq!(u.transferred, expected, "location {k}: {u:?}");
        // Until the limit is first reached, the two memories are the same.
        if k < 15 {
            assert_eq!(u, v, "location {k}");
        }
    }
    let tail = &limited[n / 2..];
    let (wm_min, wm_max) = tail.iter().fold((usize::MAX, 0), |(lo, hi), u| {
        (lo.min(u.working_memory), hi.max(u.working_memory))
    });
    let worst = tail.iter().map(|u| u.comparisons).max().unwrap_or(0);
    println!(
        "limited to {limit}: WM {wm_min}-{wm_max} locations, at most {worst} comparisons in the second half"
    );
    // WM settles within a location of where the limit is reached, and a location's cost
    // overshoots the limit by at most the words one location adds (250 new landmarks).
    assert!(wm_max - wm_min <= 2, "WM {wm_min}-{wm_max}");
    assert!(
        worst <= limit + 500 * 300,
        "worst {worst} comparisons against a limit of {limit}"
    );
    assert!(worst >= limit - 500 * 500, "the limit is used: {worst}");
}
