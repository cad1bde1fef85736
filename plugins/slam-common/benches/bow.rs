//! Bag-of-words cost at RTAB-Map's rate of one location a second with 500 descriptors each:
//! adding a location to vocabularies of 20k and 100k words, and scoring a location against
//! every indexed one.
//!
//! The vocabularies come from the simulated route of `tests/support/bow_route.rs`, as in
//! `tests/all/bow.rs`: every location sees 500 landmarks, 250 of them seen by the previous
//! location too. Added locations are of three kinds: the next location of the route (250
//! re-observed, 250 new landmarks), a revisit of an old location (500 re-observed: a loop
//! closure), and a location of landmarks never seen (500 new words, the index's worst
//! case). Only `add_signature` is timed; the signature is removed again after each, which
//! returns the vocabulary to its size. `100k-r1` repeats the 100k cases at probe radius 1
//! (exact within 32 bits instead of 48).
//!
//! `cargo bench -p vinebench-slam-common --bench bow`

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use slam_common::place::bow::{Descriptor, Dictionary, DictionaryConfig, SignatureId};

#[path = "../tests/support/bow_route.rs"]
mod bow_route;

use bow_route::{Route, landmarks, observe};

const PER_LOCATION: usize = 500;
const STRIDE: usize = 250;
const ROUTE: Route = Route {
    per_location: PER_LOCATION,
    stride: STRIDE,
};
/// Query sets per case, cycled through.
const VARIANTS: usize = 8;

struct Setup {
    vocabulary: Dictionary,
    /// Locations added so far.
    locations: usize,
    world: Vec<Descriptor>,
}

/// A vocabulary of about `words` words from the route, with room in `world` for one more
/// location.
fn setup(words: usize, config: DictionaryConfig, rng: &mut ChaCha8Rng) -> Setup {
    let locations = words / STRIDE;
    let world = ROUTE.world(locations + 1, rng);
    let mut vocabulary = Dictionary::new(config);
    let start = Instant::now();
    for k in 0..locations {
        vocabulary.add_signature(k as SignatureId, &ROUTE.location(&world, k, rng));
    }
    eprintln!(
        "{} words, {} signatures, built in {:.1} s",
        vocabulary.word_count(),
        vocabulary.signature_count(),
        start.elapsed().as_secs_f64()
    );
    Setup {
        vocabulary,
        locations,
        world,
    }
}

/// Times `add_signature` of each query set in turn, removing it again untimed.
fn time_adds(vocabulary: &mut Dictionary, sets: &[Vec<Descriptor>], iters: u64) -> Duration {
    let mut total = Duration::ZERO;
    for i in 0..iters {
        let set = &sets[i as usize % sets.len()];
        let start = Instant::now();
        black_box(vocabulary.add_signature(u64::MAX, black_box(set)));
        total += start.elapsed();
        vocabulary.remove_signature(u64::MAX);
    }
    total
}

fn bench(c: &mut Criterion) {
    let mut rng = ChaCha8Rng::seed_from_u64(42);
    let mut group = c.benchmark_group("bow");
    group
        .sample_size(20)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(4));
    let r1 = DictionaryConfig {
        probe_radius: 1,
        ..DictionaryConfig::default()
    };
    for (label, words, config) in [
        ("20k", 20_000, DictionaryConfig::default()),
        ("100k", 100_000, DictionaryConfig::default()),
        ("100k-r1", 100_000, r1),
    ] {
        let Setup {
            mut vocabulary,
            locations,
            world,
        } = setup(words, config, &mut rng);
        let next: Vec<Vec<Descriptor>> = (0..VARIANTS)
            .map(|_| ROUTE.location(&world, locations, &mut rng))
            .collect();
        let revisit: Vec<Vec<Descriptor>> = (0..VARIANTS)
            .map(|i| ROUTE.location(&world, i * locations / VARIANTS, &mut rng))
            .collect();
        let unseen: Vec<Vec<Descriptor>> = (0..VARIANTS)
            .map(|_| {
                landmarks(PER_LOCATION, &mut rng)
                    .iter()
                    .map(|d| observe(d, &mut rng))
                    .collect()
            })
            .collect();
        for (kind, sets) in [("next", &next), ("revisit", &revisit), ("unseen", &unseen)] {
            group.bench_function(
                BenchmarkId::new(format!("add_signature/{kind}"), label),
                |b| b.iter_custom(|iters| time_adds(&mut vocabulary, sets, iters)),
            );
        }

        // Scoring a revisit against every location but the 10 newest (short-term memory).
        let queries: Vec<Vec<u32>> = revisit
            .iter()
            .map(|set| vocabulary.quantize(set).into_iter().flatten().collect())
            .collect();
        let recent = (locations - 10) as SignatureId;
        let mut i = 0;
        group.bench_function(BenchmarkId::new("scores", label), |b| {
            b.iter(|| {
                i = (i + 1) % queries.len();
                black_box(vocabulary.scores(black_box(&queries[i]), |j| j >= recent))
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
