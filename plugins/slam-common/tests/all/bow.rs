//! The bag-of-words vocabulary from outside the crate: re-observed places are recognised,
//! unrelated ones add words, memory management deletes orphan words, the tf-idf and
//! likelihood formulas against hand-computed values, and the multi-index hash against a
//! linear scan on a simulated vineyard route (`support/bow_route.rs`) whose locations each
//! see 300 landmarks, half of them seen by the previous location too.

use crate::bow_route;

use bow_route::{Route, flip, landmarks, observe};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use slam_common::place::bow::{
    Descriptor, Dictionary, DictionaryConfig, SignatureId, WordId, WordMatch, adjusted_likelihood,
    hamming,
};

const PER_LOCATION: usize = 300;
const STRIDE: usize = 150;
const ROUTE: Route = Route {
    per_location: PER_LOCATION,
    stride: STRIDE,
};

/// Adds locations `0..n` of the route (signature id = location); returns each location's
/// words, in landmark order.
fn drive(
    vocabulary: &mut Dictionary,
    world: &[Descriptor],
    n: usize,
    rng: &mut ChaCha8Rng,
) -> Vec<Vec<WordId>> {
    (0..n)
        .map(|k| vocabulary.add_signature(k as SignatureId, &ROUTE.location(world, k, rng)))
        .collect()
}

fn argmax(scores: &[(SignatureId, f64)]) -> SignatureId {
    scores
        .iter()
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .expect("some score")
        .0
}

#[test]
fn revisited_location_maps_to_its_words_and_scores_highest() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let world = ROUTE.world(41, &mut rng);
    let mut vocabulary = Dictionary::default();
    let words = drive(&mut vocabulary, &world, 40, &mut rng);

    for k in [0, 17, 39] {
        let revisit = ROUTE.location(&world, k, &mut rng);
        let before = vocabulary.word_count();
        let quantised = vocabulary.quantize(&revisit);
        assert_eq!(vocabulary.word_count(), before, "quantize adds nothing");
        let again = vocabulary.add_signature(1000, &revisit);
        for (q, w) in quantised.iter().zip(&again) {
            if let Some(q) = q {
                assert_eq!(q, w, "quantize predicts add_signature");
            }
        }
        let same = again.iter().zip(&words[k]).filter(|(a, b)| a == b).count();
        let fraction = same as f64 / PER_LOCATION as f64;
        println!(
            "location {k}: {:.1}% of descriptors on the same words",
            100.0 * fraction
        );
        assert!(
            fraction >= 0.9,
            "location {k}: only {:.1}%",
            100.0 * fraction
        );

        let scores = vocabulary.scores(&again, |j| j == 1000);
        assert!(scores.iter().all(|&(j, _)| j != 1000));
        assert!(scores.windows(2).all(|w| w[0].0 < w[1].0), "sorted by id");
        assert_eq!(argmax(&scores), k as SignatureId);
        vocabulary.remove_signature(1000);
    }
}

#[test]
fn unrelated_locations_create_new_words() {
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let world = ROUTE.world(20, &mut rng);
    let mut vocabulary = Dictionary::default();
    let words = drive(&mut vocabulary, &world, 20, &mut rng);
    let newest = words.iter().flatten().max().copied().expect("words");

    // Another vineyard: landmarks never seen.
    let elsewhere = landmarks(PER_LOCATION, &mut rng);
    let descriptors: Vec<Descriptor> = elsewhere.iter().map(|d| observe(d, &mut rng)).collect();
    assert!(
        vocabulary
            .quantize(&descriptors)
            .iter()
            .all(Option::is_none)
    );
    let before = vocabulary.word_count();
    let added = vocabulary.add_signature(500, &descriptors);
    assert_eq!(vocabulary.word_count(), before + PER_LOCATION);
    let expected: Vec<WordId> = (newest + 1..).take(PER_LOCATION).collect();
    assert_eq!(added, expected, "new words numbered in descriptor order");
    for (w, d) in added.iter().zip(&descriptors) {
        assert_eq!(vocabulary.descriptor(*w), Some(d));
    }
    assert!(vocabulary.scores(&added, |j| j == 500).is_empty());

    // Descriptors of one signature never match each other's new words.
    let d: Descriptor = rng.random();
    let twins = vocabulary.add_signature(501, &[d, d, flip(&d, 1, &mut rng)]);
    assert_eq!(twins.len(), 3);
    assert!(twins[0] != twins[1] && twins[1] != twins[2] && twins[0] != twins[2]);
    // Afterwards an exact copy finds two words at distance 0 and fails the ratio test.
    assert_eq!(vocabulary.quantize(&[d]), vec![None]);
}

#[test]
fn single_word_counts_its_missing_second_neighbour_at_the_search_radius() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let d: Descriptor = rng.random();
    let mut v = Dictionary::default();
    let w = v.add_signature(1, &[d])[0];
    // R = 48 at the default probe radius: accept iff d₁ < 0.8 · 48 = 38.4.
    assert_eq!(v.search_radius(), 48);
    assert_eq!(v.quantize(&[flip(&d, 38, &mut rng)]), vec![Some(w)]);
    assert_eq!(v.quantize(&[flip(&d, 39, &mut rng)]), vec![None]);
    assert_eq!(v.quantize(&[d]), vec![Some(w)]);
    let near = flip(&d, 40, &mut rng);
    assert_eq!(
        v.nearest(&near),
        [
            Some(WordMatch {
                word: w,
                distance: 40
            }),
            None
        ]
    );
    assert_eq!(v.nearest(&flip(&d, 48, &mut rng)), [None, None]);
}

#[test]
fn removing_signatures_deletes_orphan_words() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let world = ROUTE.world(3, &mut rng);
    let mut vocabulary = Dictionary::default();
    let words = drive(&mut vocabulary, &world, 2, &mut rng);
    assert_eq!(vocabulary.signature_count(), 2);

    // Landmarks 150..300 are shared by both locations.
    let only_first: Vec<WordId> = words[0]
        .iter()
        .copied()
        .filter(|w| !words[1].contains(w))
        .collect();
    let shared: Vec<WordId> = words[0]
        .iter()
        .copied()
        .filter(|w| words[1].contains(w))
        .collect();
    assert!(only_first.len() >= STRIDE && shared.len() >= STRIDE * 9 / 10);
    let before = vocabulary.word_count();

    vocabulary.remove_signature(0);
    vocabulary.remove_signature(0); // unknown now: ignored
    assert!(!vocabulary.contains_signature(0));
    assert_eq!(vocabulary.word_count(), before - only_first.len());
    for &w in &only_first {
        assert_eq!(vocabulary.descriptor(w), None);
    }
    for &w in &shared {
        assert!(vocabulary.descriptor(w).is_some());
    }
    // The deleted words are gone from the search structure too.
    let first = ROUTE.location(&world, 0, &mut rng);
    for (q, d) in vocabulary.quantize(&first).iter().zip(&first) {
        if let Some(q) = q {
            assert!(!only_first.contains(q));
        }
        for m in vocabulary.nearest(d).into_iter().flatten() {
            assert!(!only_first.contains(&m.word));
        }
    }
    let scores = vocabulary.scores(&words[0], |_| false);
    assert_eq!(scores.len(), 1);
    assert_eq!(scores[0].0, 1);

    vocabulary.remove_signature(1);
    assert_eq!(vocabulary.word_count(), 0);
    assert_eq!(vocabulary.signature_count(), 0);
    assert!(vocabulary.nearest(&first[0]).iter().all(Option::is_none));
    // Word ids are not reused.
    let next = vocabulary.add_signature(7, &first[..1]);
    assert!(next[0] > *words.iter().flatten().max().expect("words"));
}

#[test]
fn tf_idf_matches_hand_computation() {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let [a, b, c, d, e]: [Descriptor; 5] = std::array::from_fn(|_| rng.random());
    let mut v = Dictionary::default();
    let s1 = v.add_signature(1, &[a, b]);
    let s2 = v.add_signature(2, &[flip(&a, 1, &mut rng), flip(&a, 2, &mut rng), c]);
    let s3 = v.add_signature(3, &[flip(&b, 3, &mut rng), flip(&c, 1, &mut rng), d]);
    let s4 = v.add_signature(4, &[flip(&d, 2, &mut rng), e]);
    let (wa, wb, wc, wd, we) = (s1[0], s1[1], s2[2], s3[2], s4[1]);
    assert_eq!(s2, vec![wa, wa, wc]);
    assert_eq!(s3, vec![wb, wc, wd]);
    assert_eq!(s4, vec![wd, we]);
    assert_eq!(v.signature_words(2), Some(&[(wa, 2), (wc, 1)][..]));

    // N = 4; n_a = n_c = 2, n_e = 1; n_1 = n_4 = 2, n_2 = n_3 = 3. A repeated and an
    // unknown query word change nothing.
    let query = [wa, wc, we, wa, 999_999];
    let ln = f64::ln;
    let expected = [
        (1, 0.5 * ln(2.0)),                             // a: 1/2 · ln(4/2)
        (2, 2.0 / 3.0 * ln(2.0) + 1.0 / 3.0 * ln(2.0)), // a: 2/3 · ln 2, c: 1/3 · ln 2
        (3, 1.0 / 3.0 * ln(2.0)),                       // c
        (4, 0.5 * ln(4.0)),                             // e: 1/2 · ln(4/1)
    ];
    let close = |got: &[(SignatureId, f64)], want: &[(SignatureId, f64)]| {
        assert_eq!(got.len(), want.len(), "{got:?} vs {want:?}");
        for (g, w) in got.iter().zip(want) {
            assert_eq!(g.0, w.0);
            assert!((g.1 - w.1).abs() < 1e-12, "{got:?} vs {want:?}");
        }
    };
    close(&v.scores(&query, |_| false), &expected);

    // Excluding 3: N = 3, n_a = 2, n_c = 1, n_e = 1.
    close(
        &v.scores(&query, |j| j == 3),
        &[
            (1, 0.5 * ln(1.5)),
            (2, 2.0 / 3.0 * ln(1.5) + 1.0 / 3.0 * ln(3.0)),
            (4, 0.5 * ln(3.0)),
        ],
    );
    // A word every considered signature holds scores 0, and they are listed.
    close(&v.scores(&[wa], |j| j > 2), &[(1, 0.0), (2, 0.0)]);
    assert!(v.scores(&query, |_| true).is_empty());
    assert!(v.scores(&[], |_| false).is_empty());
    assert_eq!(v.signature_words(4), Some(&[(wd, 1), (we, 1)][..]));
}

#[test]
fn adjusted_likelihood_matches_hand_computation() {
    // Positive scores 1, 2, 3, 10: μ = 4, σ² = (9 + 4 + 1 + 36)/4 = 12.5; only 10 ≥ μ + σ.
    let sigma = 12.5f64.sqrt();
    let (l, new_place) = adjusted_likelihood(&[(1, 1.0), (2, 2.0), (3, 3.0), (4, 10.0), (5, 0.0)]);
    let want = [
        (1, 1.0),
        (2, 1.0),
        (3, 1.0),
        (4, (10.0 - sigma) / 4.0),
        (5, 1.0),
    ];
    assert_eq!(l.len(), want.len());
    for (g, w) in l.iter().zip(&want) {
        assert_eq!(g.0, w.0);
        assert!((g.1 - w.1).abs() < 1e-12, "{l:?}");
    }
    assert!((new_place - (4.0 / sigma + 1.0)).abs() < 1e-12);
    assert!((l[3].1 - 1.616_116_523_516_815_6).abs() < 1e-12);
    assert!((new_place - 2.131_370_849_898_476).abs() < 1e-12);

    // Degenerate statistics: no evidence either way.
    assert_eq!(adjusted_likelihood(&[]), (vec![], 1.0));
    assert_eq!(
        adjusted_likelihood(&[(3, 0.7), (8, 0.7)]),
        (vec![(3, 1.0), (8, 1.0)], 1.0)
    );
    assert_eq!(adjusted_likelihood(&[(3, 0.0)]), (vec![(3, 1.0)], 1.0));
    assert_eq!(adjusted_likelihood(&[(3, 0.4)]), (vec![(3, 1.0)], 1.0));
}

/// The nearest and second-nearest words of a linear scan (ties to the smaller id).
fn brute_two(vocabulary: &Dictionary, q: &Descriptor) -> [Option<WordMatch>; 2] {
    let mut all: Vec<WordMatch> = vocabulary
        .words()
        .map(|(word, d)| WordMatch {
            word,
            distance: hamming(q, d),
        })
        .collect();
    all.sort_by_key(|m| (m.distance, m.word));
    [all.first().copied(), all.get(1).copied()]
}

#[test]
fn multi_index_hash_agrees_with_linear_scan() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let locations = 140;
    let world = ROUTE.world(locations + 10, &mut rng);
    let mut vocabulary = Dictionary::default();
    drive(&mut vocabulary, &world, locations, &mut rng);
    // Memory management: every third location leaves, then the route goes on, so the index
    // has seen deletions and reused slots.
    for k in (0..locations).step_by(3) {
        vocabulary.remove_signature(k as SignatureId);
    }
    for k in locations..locations + 10 {
        vocabulary.add_signature(k as SignatureId, &ROUTE.location(&world, k, &mut rng));
    }
    let radius = vocabulary.search_radius();
    let nndr = vocabulary.config().nndr;
    println!("{} words, R = {radius}", vocabulary.word_count());
    assert!(vocabulary.word_count() > 15_000);

    // Queries: re-observations of landmarks, descriptors unlike anything, and hard cases
    // (a landmark with 11–40 bits flipped).
    let mut queries: Vec<(&str, Descriptor)> = Vec::new();
    for _ in 0..1200 {
        let l = rng.random_range(0..world.len());
        queries.push(("observation", observe(&world[l], &mut rng)));
    }
    for _ in 0..400 {
        queries.push(("random", rng.random()));
    }
    for _ in 0..400 {
        let l = rng.random_range(0..world.len());
        let bits = rng.random_range(11..=40);
        queries.push(("hard", flip(&world[l], bits, &mut rng)));
    }

    let descriptors: Vec<Descriptor> = queries.iter().map(|q| q.1).collect();
    let quantised = vocabulary.quantize(&descriptors);
    let (mut lowe_agree, mut lowe_total) = (0usize, 0usize);
    let (mut hard_agree, mut two_nn_agree) = (0usize, 0usize);
    for ((kind, q), quantised) in queries.iter().zip(&quantised) {
        let exact = brute_two(&vocabulary, q);
        // The index's 2-NN is the scan's 2-NN restricted to distances below R: always.
        let within = exact.map(|m| m.filter(|m| m.distance < radius));
        assert_eq!(vocabulary.nearest(q), within, "{kind} query");
        two_nn_agree += usize::from(vocabulary.nearest(q) == exact);

        // Quantisation is the capped ratio test, exactly.
        let d1 = exact[0].map_or(u32::MAX, |m| m.distance);
        let d2 = exact[1].map_or(u32::MAX, |m| m.distance);
        let capped =
            ((d1 as f32) < nndr * d2.min(radius) as f32).then(|| exact[0].expect("a word").word);
        assert_eq!(*quantised, capped, "{kind} query");

        // Against the plain (uncapped) ratio test of a linear scan.
        let lowe = ((d1 as f32) < nndr * d2 as f32).then(|| exact[0].expect("a word").word);
        if *kind == "hard" {
            hard_agree += usize::from(*quantised == lowe);
        } else {
            lowe_total += 1;
            lowe_agree += usize::from(*quantised == lowe);
        }
    }
    let pct = |a: usize, n: usize| 100.0 * a as f64 / n as f64;
    let lowe_pct = pct(lowe_agree, lowe_total);
    println!(
        "quantisation = uncapped linear-scan ratio test: {lowe_pct:.2}% of {lowe_total} \
         observations and random queries; {:.2}% of 400 hard queries",
        pct(hard_agree, 400)
    );
    println!(
        "unrestricted 2-NN (both ids) = linear scan: {:.2}% of {} queries",
        pct(two_nn_agree, queries.len()),
        queries.len()
    );
    assert!(lowe_pct >= 95.0);
}

#[test]
fn deterministic() {
    let build = || {
        let mut rng = ChaCha8Rng::seed_from_u64(6);
        let world = ROUTE.world(30, &mut rng);
        let mut vocabulary = Dictionary::new(DictionaryConfig {
            nndr: 0.8,
            probe_radius: 1,
        });
        let words = drive(&mut vocabulary, &world, 30, &mut rng);
        vocabulary.remove_signature(4);
        let scores = vocabulary.scores(&words[12], |j| j == 12);
        (
            words,
            scores,
            vocabulary.words().map(|(w, d)| (w, *d)).collect::<Vec<_>>(),
        )
    };
    assert_eq!(build(), build());
}
