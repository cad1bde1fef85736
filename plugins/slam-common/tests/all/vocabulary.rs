//! The DBoW2-style hierarchical vocabulary from outside the crate: deterministic training
//! (whatever the thread count), the tree's invariants, the tf-idf vector and the direct
//! index against a word-by-word recomputation, the L1 score on hand-computed vectors, place
//! recognition along a simulated vineyard route (`support/bow_route.rs`: locations see 300
//! landmarks each, half of them shared with the next location), and the file format —
//! round trip, documented size, and errors (not panics) on corrupt or truncated files.

#[allow(dead_code)]
use crate::bow_route;

use std::time::Instant;

use bow_route::{Route, landmarks, observe};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use slam_common::place::vocabulary::{
    BowVector, Descriptor, FeatureVector, NodeId, TrainConfig, Vocabulary, VocabularyError, WordId,
};

const ROUTE: Route = Route {
    per_location: 300,
    stride: 150,
};
const LOCATIONS: usize = 30;

/// A small tree for the route tests: 8⁴ = 4096 possible words for ~4.6k landmarks.
const SMALL: TrainConfig = TrainConfig {
    k: 8,
    levels: 4,
    seed: 7,
    max_iterations: 10,
};

/// Training images along the route: one observation of every location.
fn route_images(world: &[Descriptor], rng: &mut ChaCha8Rng) -> Vec<Vec<Descriptor>> {
    (0..LOCATIONS)
        .map(|k| ROUTE.location(world, k, rng))
        .collect()
}

/// `n` images of `per_image` descriptors: observations of landmarks (families of four
/// around random prototypes), each image seeing a random window of them.
fn random_images(n: usize, per_image: usize, seed: u64) -> Vec<Vec<Descriptor>> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let world = landmarks(n * per_image / 4 + per_image, &mut rng);
    (0..n)
        .map(|_| {
            let start = rng.random_range(0..world.len() - per_image);
            world[start..start + per_image]
                .iter()
                .map(|d| observe(d, &mut rng))
                .collect()
        })
        .collect()
}

fn bytes(vocabulary: &Vocabulary) -> Vec<u8> {
    let mut out = Vec::new();
    vocabulary.write_to(&mut out).expect("write to memory");
    out
}

fn train_with_threads(
    images: &[Vec<Descriptor>],
    config: &TrainConfig,
    threads: usize,
) -> Vocabulary {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("thread pool")
        .install(|| Vocabulary::train(images, config).expect("train"))
}

fn hamming(a: &Descriptor, b: &Descriptor) -> u32 {
    a.iter().zip(b).map(|(x, y)| (x ^ y).count_ones()).sum()
}

#[test]
fn training_is_deterministic_and_depends_on_the_seed() {
    // Big enough (20k descriptors) that the root's k-means is split across threads.
    let images = random_images(100, 200, 1);
    let config = TrainConfig {
        seed: 3,
        ..TrainConfig::default()
    };
    let one = train_with_threads(&images, &config, 1);
    let four = train_with_threads(&images, &config, 4);
    let again = Vocabulary::train(&images, &config).expect("train");
    assert_eq!(one, four, "same seed, different thread counts");
    assert_eq!(one, again);
    assert_eq!(bytes(&one), bytes(&four), "byte-identical files");
    assert_eq!(bytes(&one), bytes(&again));

    let other = Vocabulary::train(&images, &TrainConfig { seed: 4, ..config }).expect("train");
    assert_ne!(one, other, "a different seed gives a different vocabulary");
    assert_ne!(bytes(&one), bytes(&other));
}

#[test]
fn tree_is_breadth_first_with_median_centres_and_idf_weights() {
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let world = ROUTE.world(LOCATIONS, &mut rng);
    let images = route_images(&world, &mut rng);
    let vocabulary = Vocabulary::train(&images, &SMALL).expect("train");
    assert_eq!((vocabulary.k(), vocabulary.levels()), (8, 4));
    assert_eq!(vocabulary.training_images(), LOCATIONS as u64);

    // Breadth-first numbering, consecutive children, words = leaves in node order.
    let mut expected_first = 1;
    let mut words = 0;
    for node in 0..vocabulary.node_count() as NodeId {
        let children = vocabulary.children(node);
        if !children.is_empty() {
            assert_eq!(children.start, expected_first, "children of {node}");
            assert!(children.len() <= vocabulary.k());
        }
        expected_first = children.end.max(expected_first);
        for child in children {
            assert_eq!(vocabulary.parent(child), Some(node));
            assert_eq!(vocabulary.depth(child), vocabulary.depth(node) + 1);
            assert!(vocabulary.depth(child) <= vocabulary.levels());
            if node > 0 {
                assert!(vocabulary.depth(child) >= vocabulary.depth(child - 1));
            }
        }
        match vocabulary.node_word(node) {
            Some(w) => {
                assert_eq!(w, words);
                assert_eq!(vocabulary.word_node(w), node);
                assert!(vocabulary.children(node).is_empty());
                words += 1;
            }
            None => assert!(node == 0 || !vocabulary.children(node).is_empty()),
        }
    }
    assert_eq!(vocabulary.parent(0), None);
    assert_eq!(words as usize, vocabulary.word_count());
    assert!(
        vocabulary.word_count() > 1000,
        "{} words",
        vocabulary.word_count()
    );

    // Every training descriptor reaches a word by the nearest child at each level, and the
    // idf of a word is ln(N / images holding it).
    let mut holders = vec![0usize; vocabulary.word_count()];
    for image in &images {
        let mut seen: Vec<WordId> = image.iter().map(|d| vocabulary.word_of(d).0).collect();
        seen.sort_unstable();
        seen.dedup();
        for w in seen {
            holders[w as usize] += 1;
        }
    }
    for (w, &h) in holders.iter().enumerate() {
        assert!(h > 0, "word {w} holds no training descriptor");
        let idf = (LOCATIONS as f64 / h as f64).ln();
        assert!((vocabulary.word_weight(w as WordId) - idf).abs() < 1e-12);
    }
    for d in images.iter().flatten().step_by(37) {
        let (w, weight) = vocabulary.word_of(d);
        assert_eq!(weight, vocabulary.word_weight(w));
        let mut node = 0;
        while !vocabulary.children(node).is_empty() {
            node = vocabulary
                .children(node)
                .min_by_key(|&c| (hamming(d, &vocabulary.node_descriptor(c)), c))
                .expect("a child");
        }
        assert_eq!(vocabulary.word_node(w), node);
    }
}

#[test]
fn nodes_with_at_most_k_distinct_descriptors_get_one_leaf_each() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let a: Descriptor = rng.random();
    let b: Descriptor = rng.random();
    let c: Descriptor = rng.random();
    // Three distinct values, duplicated, in two images: the root gets three leaves.
    let images = vec![vec![a, b, a, a], vec![c, b, c], vec![]];
    let vocabulary = Vocabulary::train(&images, &TrainConfig::default()).expect("train");
    assert_eq!(vocabulary.word_count(), 3);
    assert_eq!(vocabulary.node_count(), 4);
    assert_eq!(vocabulary.children(0), 1..4);
    let expected = [
        (a, (3.0f64 / 1.0).ln()),
        (b, (3.0f64 / 2.0).ln()),
        (c, 3.0f64.ln()),
    ];
    for (w, (d, idf)) in expected.into_iter().enumerate() {
        assert_eq!(vocabulary.node_descriptor(w as NodeId + 1), d);
        assert_eq!(vocabulary.word_of(&d), (w as WordId, idf));
    }

    // A single repeated descriptor still makes one word under the root.
    let single = Vocabulary::train(&[vec![a; 50]], &TrainConfig::default()).expect("train");
    assert_eq!((single.node_count(), single.word_count()), (2, 1));
    assert_eq!(single.word_of(&b), (0, 0.0));
}

#[test]
fn invalid_training_input_is_an_error() {
    let images = random_images(2, 20, 9);
    for config in [
        TrainConfig {
            k: 1,
            ..TrainConfig::default()
        },
        TrainConfig {
            levels: 0,
            ..TrainConfig::default()
        },
        TrainConfig {
            max_iterations: 0,
            ..TrainConfig::default()
        },
    ] {
        assert!(matches!(
            Vocabulary::train(&images, &config),
            Err(VocabularyError::InvalidConfig(_))
        ));
    }
    assert!(matches!(
        Vocabulary::train(&[vec![], vec![]], &TrainConfig::default()),
        Err(VocabularyError::NoDescriptors)
    ));
}

#[test]
fn bow_vector_is_normalised_tf_idf_and_direct_index_groups_features_under_ancestors() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let world = ROUTE.world(LOCATIONS, &mut rng);
    let images = route_images(&world, &mut rng);
    let vocabulary = Vocabulary::train(&images, &SMALL).expect("train");
    let query = ROUTE.location(&world, 11, &mut rng);

    for levels_up in [0, 1, 2, 4, 9] {
        let (bow, features) = vocabulary.transform(&query, levels_up);

        // tf-idf, recomputed descriptor by descriptor.
        let mut expected = vec![0.0; vocabulary.word_count()];
        for d in &query {
            let (w, weight) = vocabulary.word_of(d);
            expected[w as usize] += weight / query.len() as f64;
        }
        let norm: f64 = expected.iter().sum();
        let expected: Vec<(WordId, f64)> = expected
            .iter()
            .enumerate()
            .filter(|&(_, &v)| v > 0.0)
            .map(|(w, &v)| (w as WordId, v / norm))
            .collect();
        assert_eq!(bow.entries.len(), expected.len());
        for (&(w, v), &(ew, ev)) in bow.entries.iter().zip(&expected) {
            assert_eq!(w, ew);
            assert!((v - ev).abs() < 1e-12, "word {w}: {v} vs {ev}");
        }
        let sum: f64 = bow.entries.iter().map(|&(_, v)| v).sum();
        assert!((sum - 1.0).abs() < 1e-12);

        // Direct index: sorted by node, every feature exactly once, under the node of depth
        // L − levels_up above its word (the word itself if shallower).
        assert!(features.entries.windows(2).all(|p| p[0].0 < p[1].0));
        let mut seen = vec![0; query.len()];
        let target = vocabulary.levels().saturating_sub(levels_up);
        for (node, list) in &features.entries {
            assert!(list.windows(2).all(|p| p[0] < p[1]));
            for &i in list {
                seen[i as usize] += 1;
                let mut ancestor = vocabulary.word_node(vocabulary.word_of(&query[i as usize]).0);
                while vocabulary.depth(ancestor) > target {
                    ancestor = vocabulary.parent(ancestor).expect("not the root");
                }
                assert_eq!(*node, ancestor, "feature {i}, levels_up {levels_up}");
            }
        }
        assert!(seen.iter().all(|&s| s == 1), "every feature exactly once");
        if levels_up >= vocabulary.levels() {
            assert_eq!(features.entries.len(), 1);
            assert_eq!(features.entries[0].0, 0);
        }
    }

    let (bow, features) = vocabulary.transform(&[], 4);
    assert_eq!(bow, BowVector::default());
    assert_eq!(features, FeatureVector::default());
}

#[test]
fn score_is_the_l1_score() {
    let v = |e: &[(WordId, f64)]| BowVector {
        entries: e.to_vec(),
    };
    let a = v(&[(1, 0.5), (2, 0.5)]);
    let b = v(&[(2, 0.25), (3, 0.75)]);
    // 1 − ½ (0.5 + 0.25 + 0.75) = 0.25.
    assert!((Vocabulary::score(&a, &b) - 0.25).abs() < 1e-15);
    assert!((Vocabulary::score(&b, &a) - 0.25).abs() < 1e-15);
    // Scale-invariant: normalised inside.
    let a3 = v(&[(1, 1.5), (2, 1.5)]);
    assert!((Vocabulary::score(&a3, &b) - 0.25).abs() < 1e-15);
    assert!((Vocabulary::score(&a, &a3) - 1.0).abs() < 1e-15);
    let c = v(&[(1, 0.2), (4, 0.3), (7, 0.5)]);
    let d = v(&[(1, 0.6), (7, 0.1), (9, 0.3)]);
    // min over common words: 0.2 + 0.1.
    assert!((Vocabulary::score(&c, &d) - 0.3).abs() < 1e-15);

    assert!((Vocabulary::score(&c, &c) - 1.0).abs() < 1e-15);
    assert_eq!(Vocabulary::score(&a, &v(&[(0, 0.4), (5, 0.6)])), 0.0);
    assert_eq!(Vocabulary::score(&a, &BowVector::default()), 0.0);
    assert_eq!(
        Vocabulary::score(&BowVector::default(), &BowVector::default()),
        0.0
    );
}

#[test]
fn route_images_score_highest_against_their_neighbours() {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let world = ROUTE.world(LOCATIONS, &mut rng);
    // Trained on one pass along the route, queried with a second pass (fresh observation
    // noise), and with a vocabulary trained on another world entirely.
    let own = Vocabulary::train(&route_images(&world, &mut rng), &SMALL).expect("train");
    let other_world = ROUTE.world(LOCATIONS, &mut rng);
    let foreign = Vocabulary::train(
        &route_images(&other_world, &mut rng),
        &TrainConfig::default(),
    )
    .expect("train");
    let pass = route_images(&world, &mut rng);

    for (name, vocabulary) in [("own", &own), ("foreign", &foreign)] {
        let bows: Vec<BowVector> = pass.iter().map(|d| vocabulary.transform(d, 4).0).collect();
        let mut worst_margin = f64::INFINITY;
        for (i, bow) in bows.iter().enumerate() {
            let self_score = Vocabulary::score(bow, bow);
            assert!(
                (self_score - 1.0).abs() < 1e-12,
                "{name}: self score {self_score}"
            );
            let scores: Vec<f64> = bows.iter().map(|b| Vocabulary::score(bow, b)).collect();
            let best = (0..LOCATIONS)
                .filter(|&j| j != i)
                .max_by(|&a, &b| scores[a].total_cmp(&scores[b]))
                .expect("other images");
            assert_eq!(best.abs_diff(i), 1, "{name}: image {i} best matches {best}");
            let neighbour = [i.wrapping_sub(1), i + 1]
                .into_iter()
                .filter(|&j| j < LOCATIONS)
                .map(|j| scores[j])
                .fold(f64::INFINITY, f64::min);
            let far = (0..LOCATIONS)
                .filter(|&j| j.abs_diff(i) >= 2)
                .map(|j| scores[j])
                .fold(0.0, f64::max);
            assert!(neighbour > far, "{name}: image {i}: {neighbour} vs {far}");
            worst_margin = worst_margin.min(neighbour - far);
        }
        println!("{name} vocabulary: worst neighbour − far score margin {worst_margin:.3}");
    }
}

#[test]
fn save_load_round_trip_and_file_size() {
    let images = random_images(60, 150, 6);
    let vocabulary = Vocabulary::train(&images, &TrainConfig::default()).expect("train");
    let dir = std::env::temp_dir().join(format!("vinebench-vocabulary-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join("vocabulary.bin");
    vocabulary.save(&path).expect("save");
    let loaded = Vocabulary::load(&path).expect("load");
    assert_eq!(loaded, vocabulary);
    let file = std::fs::read(&path).expect("read back");
    assert_eq!(file, bytes(&vocabulary));
    // The documented size: 12 + 36·nodes + 8·words.
    assert_eq!(
        file.len(),
        12 + 36 * vocabulary.node_count() + 8 * vocabulary.word_count()
    );
    let mut cursor = file.as_slice();
    assert_eq!(
        Vocabulary::read_from(&mut cursor).expect("read"),
        vocabulary
    );
    assert!(cursor.is_empty(), "read_from reads exactly the vocabulary");
    // Saving over an existing file replaces it and leaves no temporary behind.
    vocabulary.save(&path).expect("save again");
    let entries: Vec<_> = std::fs::read_dir(&dir).expect("list").collect();
    assert_eq!(entries.len(), 1);
    std::fs::remove_dir_all(&dir).expect("clean up");

    let query = &images[3];
    assert_eq!(loaded.transform(query, 4), vocabulary.transform(query, 4));
}

#[test]
fn corrupt_or_truncated_files_are_errors() {
    let images = random_images(20, 100, 8);
    let config = TrainConfig {
        k: 6,
        levels: 3,
        ..TrainConfig::default()
    };
    let good = bytes(&Vocabulary::train(&images, &config).expect("train"));
    let read = |b: &[u8]| Vocabulary::read_from(&mut &b[..]);
    assert!(read(&good).is_ok());

    // Every truncation, at a sample of lengths including all of the header.
    for len in (0..good.len()).filter(|&l| l < 64 || l % 97 == 0 || l + 8 >= good.len()) {
        match read(&good[..len]) {
            Err(VocabularyError::Truncated(_)) => {}
            other => panic!("truncated to {len} of {}: {other:?}", good.len()),
        }
    }

    let mut bad = good.clone();
    bad[0] = b'X';
    assert!(matches!(read(&bad), Err(VocabularyError::BadMagic { .. })));
    let mut bad = good.clone();
    bad[8] = 2;
    assert!(matches!(
        read(&bad),
        Err(VocabularyError::UnsupportedVersion { found: 2 })
    ));
    // Header fields out of range are reported before anything is read.
    for (at, value) in [(12, 1u32), (16, 0), (16, 99), (20, 1), (24, 0)] {
        let mut bad = good.clone();
        bad[at..at + 4].copy_from_slice(&value.to_le_bytes());
        assert!(
            matches!(read(&bad), Err(VocabularyError::Corrupt(_))),
            "header field at {at} = {value}"
        );
    }
    // A huge node count: truncated, not an allocation of the stated size.
    let mut bad = good.clone();
    bad[20..24].copy_from_slice(&0xffff_fff0u32.to_le_bytes());
    assert!(matches!(read(&bad), Err(VocabularyError::Truncated(_))));

    // Flipped bits anywhere in the content: a checksum error, never a panic.
    let mut rng = ChaCha8Rng::seed_from_u64(10);
    for _ in 0..200 {
        let mut bad = good.clone();
        let at = rng.random_range(36..good.len());
        bad[at] ^= 1 << rng.random_range(0..8);
        assert!(read(&bad).is_err(), "flipped a bit of byte {at}");
    }
    let mut bad = good.clone();
    let at = 40;
    bad[at] ^= 0x10;
    assert!(matches!(read(&bad), Err(VocabularyError::Checksum { .. })));

    // Structural corruption with a valid checksum: a child count above k, a count that
    // breaks the tree, a negative weight.
    let reseal = |mut b: Vec<u8>| {
        let n = b.len() - 8;
        let hash = fnv1a(&b[..n]);
        b[n..].copy_from_slice(&hash.to_le_bytes());
        b
    };
    assert!(read(&reseal(good.clone())).is_ok(), "test's FNV-1a matches");
    let mut bad = good.clone();
    bad[36..40].copy_from_slice(&7u32.to_le_bytes());
    let error = read(&reseal(bad)).expect_err("7 children with k = 6");
    assert!(error.to_string().contains("children"), "{error}");
    let mut bad = good.clone();
    let root_children = u32::from_le_bytes(good[36..40].try_into().unwrap());
    bad[36..40].copy_from_slice(&(root_children - 1).to_le_bytes());
    assert!(matches!(
        read(&reseal(bad)),
        Err(VocabularyError::Corrupt(_))
    ));
    let mut bad = good.clone();
    let weight = good.len() - 16;
    bad[weight..weight + 8].copy_from_slice(&(-1.0f64).to_le_bytes());
    let error = read(&reseal(bad)).expect_err("negative weight");
    assert!(error.to_string().contains("weight"), "{error}");

    // load: a missing file, and trailing bytes.
    let dir = std::env::temp_dir().join(format!("vinebench-vocab-bad-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let missing = Vocabulary::load(&dir.join("missing.bin")).expect_err("missing");
    assert!(matches!(missing, VocabularyError::File { .. }), "{missing}");
    let trailing = dir.join("trailing.bin");
    let mut long = good.clone();
    long.push(0);
    std::fs::write(&trailing, &long).expect("write");
    assert!(matches!(
        Vocabulary::load(&trailing),
        Err(VocabularyError::Corrupt(_))
    ));
    std::fs::remove_dir_all(&dir).expect("clean up");
}

/// FNV-1a 64, as documented for the file's checksum.
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3)
    })
}

#[test]
fn training_and_transform_timings() {
    // ~200k descriptors, 1000 images of 200: printed, not asserted (debug builds are slow).
    let images = random_images(1000, 200, 11);
    let start = Instant::now();
    let vocabulary = Vocabulary::train(&images, &TrainConfig::default()).expect("train");
    let train = start.elapsed();
    let file = bytes(&vocabulary);
    let query: Vec<Descriptor> = random_images(5, 200, 12).concat();
    let start = Instant::now();
    let runs = 20;
    for _ in 0..runs {
        std::hint::black_box(vocabulary.transform(std::hint::black_box(&query), 4));
    }
    let transform = start.elapsed() / runs;
    println!(
        "trained on {} descriptors in {train:.2?}: {} nodes, {} words, {:.1} MB file; \
         transform of {} descriptors: {transform:.2?}",
        images.iter().map(Vec::len).sum::<usize>(),
        vocabulary.node_count(),
        vocabulary.word_count(),
        file.len() as f64 / 1e6,
        query.len(),
    );
}

/// The size of a full-size vocabulary file: k = 10, L = 6 trained on 500k descriptors.
/// Ignored by default (about ten seconds of training in the dev profile); run with
/// `cargo test -p vinebench-slam-common --test vocabulary -- --ignored`.
#[test]
#[ignore = "trains on 500k descriptors"]
fn full_size_vocabulary_file_stays_well_under_50_mb() {
    let images = random_images(2500, 200, 13);
    let start = Instant::now();
    let vocabulary = Vocabulary::train(&images, &TrainConfig::default()).expect("train");
    let train = start.elapsed();
    let size = bytes(&vocabulary).len();
    println!(
        "trained on 500000 descriptors in {train:.2?}: {} nodes, {} words, {:.1} MB file",
        vocabulary.node_count(),
        vocabulary.word_count(),
        size as f64 / 1e6
    );
    assert!(size < 35_000_000, "{size} bytes");
}
