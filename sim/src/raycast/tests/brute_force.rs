//! The BVH must give exactly the brute-force answer: same triangle test, same tie rule.

use super::{point_in, rng, soup, unit_dir};
use crate::raycast::{BruteForce, Bvh, RayCaster};

#[test]
fn bvh_matches_brute_force_on_random_soup() {
    let mut rng = rng(7);
    let mesh = soup(&mut rng, 3000, 10.0, 1.5);
    let bvh = Bvh::build(&mesh);
    let portable = bvh.clone().portable();
    let brute = BruteForce::build(&mesh);
    let mut hits = 0;
    for i in 0..20_000 {
        // Origins inside and outside the scene bounds, some t ranges clipped.
        let origin = point_in(&mut rng, -14.0, 14.0);
        let dir = unit_dir(&mut rng);
        let (t_min, t_max) = if i % 3 == 0 {
            (rng.random_range(0.0..5.0), rng.random_range(5.0..20.0))
        } else {
            (0.0, f32::INFINITY)
        };
        let expected = brute.cast(&origin, &dir, t_min, t_max);
        let got = bvh.cast(&origin, &dir, t_min, t_max);
        assert_eq!(
            got, expected,
            "ray {i} from {origin:?} along {dir:?} in [{t_min}, {t_max}]: expected the brute-force hit"
        );
        assert_eq!(
            portable.cast(&origin, &dir, t_min, t_max),
            expected,
            "ray {i} from {origin:?} along {dir:?} in [{t_min}, {t_max}]: expected the brute-force hit from the portable kernel"
        );
        hits += usize::from(got.is_some());
    }
    assert!(
        (5_000..19_000).contains(&hits),
        "expected a mix of hits and misses, got {hits} hits of 20000"
    );
}

#[test]
fn the_avx2_kernel_runs_where_the_cpu_has_it() {
    let bvh = Bvh::build(&soup(&mut rng(6), 100, 5.0, 1.0));
    #[cfg(target_arch = "x86_64")]
    assert_eq!(
        bvh.uses_avx2(),
        std::arch::is_x86_feature_detected!("avx2"),
        "expected the AVX2 kernel exactly on CPUs with AVX2"
    );
    assert!(
        !bvh.portable().uses_avx2(),
        "expected `portable` to turn the AVX2 kernel off"
    );
}

#[test]
fn cast_fan_matches_cast() {
    let mut rng = rng(8);
    let mesh = soup(&mut rng, 2000, 5.0, 1.0);
    let bvh = Bvh::build(&mesh);
    for _ in 0..50 {
        let origin = point_in(&mut rng, -6.0, 6.0);
        let dirs: Vec<_> = (0..64).map(|_| unit_dir(&mut rng)).collect();
        let mut out = vec![None; dirs.len()];
        bvh.cast_fan(&origin, &dirs, 0.1, 30.0, &mut out);
        for (dir, got) in dirs.iter().zip(&out) {
            let expected = bvh.cast(&origin, dir, 0.1, 30.0);
            assert_eq!(
                *got, expected,
                "fan ray along {dir:?}: expected the single-ray hit"
            );
        }
    }
}

use rand::Rng;

#[test]
fn heap_stack_for_deep_trees_gives_the_same_hits() {
    // Trees deeper than the on-stack traversal stack allows (pathological meshes) get a heap
    // stack; the same tree flagged as deep must answer the same.
    let mut rng = rng(9);
    let mesh = soup(&mut rng, 2000, 5.0, 1.0);
    let bvh = Bvh::build(&mesh);
    let deep = bvh.clone().with_depth_for_test(100);
    for _ in 0..2000 {
        let origin = point_in(&mut rng, -6.0, 6.0);
        let dir = unit_dir(&mut rng);
        let expected = bvh.cast(&origin, &dir, 0.0, f32::INFINITY);
        let got = deep.cast(&origin, &dir, 0.0, f32::INFINITY);
        assert_eq!(
            got, expected,
            "ray from {origin:?} along {dir:?}: expected the on-stack answer"
        );
    }
}
