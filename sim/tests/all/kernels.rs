//! The BVH's two traversal kernels (AVX2 where the CPU has it, portable everywhere) on the
//! default world: full VLP-16 sweeps from poses along S3 and random rays through the whole
//! scene must get the very same answer, `t` bit for bit and the triangle, from both, and the
//! sweeps cast in fans must equal the same rays cast one by one.

use nalgebra::{Point3, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use sim::Simulation;
use sim::config::SimConfig;
use sim::raycast::{Bvh, RayCaster};
use sim::sensors::vlp16_directions;

#[test]
fn avx2_and_portable_kernels_give_identical_hits_on_the_vineyard() {
    let cfg = SimConfig::default();
    let sim = Simulation::new(&cfg, "s3", 0).expect("s3 builds");
    let fast = Bvh::build(&sim.world.mesh);
    let portable = fast.clone().portable();
    let mut rays: Vec<(Point3<f32>, Vector3<f32>)> = Vec::new();
    // Sweeps from 6 poses along the route, as the lidar casts them.
    let dirs = vlp16_directions(&cfg.sensors.lidar);
    let poses = 6;
    for k in 0..poses {
        let pose = sim
            .trajectory
            .pose(sim.duration_ns() * (2 * k + 1) / (2 * poses));
        let o: Point3<f32> =
            Point3::from((pose.translation.vector + Vector3::new(0.0, 0.0, 1.56)).cast());
        let rot = pose.rotation.cast::<f32>();
        let world: Vec<Vector3<f32>> = dirs.iter().map(|d| rot * d).collect();
        let mut a = vec![None; world.len()];
        let mut b = vec![None; world.len()];
        for ((d, a), b) in world.chunks(16).zip(a.chunks_mut(16)).zip(b.chunks_mut(16)) {
            fast.cast_fan(&o, d, 0.9, 130.0, a);
            portable.cast_fan(&o, d, 0.9, 130.0, b);
        }
        let hits = a.iter().filter(|h| h.is_some()).count();
        assert!(
            hits > world.len() / 3,
            "pose {k}: expected most of the sweep to hit the vineyard, got {hits} of {}",
            world.len()
        );
        for (i, d) in world.iter().enumerate() {
            assert_eq!(a[i], b[i], "pose {k}, ray {i}: the kernels disagree");
            assert_eq!(
                fast.cast(&o, d, 0.9, 130.0),
                a[i],
                "pose {k}, ray {i}: the single ray and the fan disagree"
            );
            rays.push((o, *d));
        }
    }
    // Random rays from anywhere in the scene's box (and up to 3 m above it).
    let (lo, hi) = sim.world.mesh.bounds().expect("non-empty world");
    let mut rng = ChaCha8Rng::seed_from_u64(23);
    let mut hits = 0;
    for i in 0..100_000 {
        let (o, d) = crate::random_ray(&mut rng, &lo, &hi);
        let a = fast.cast(&o, &d, 0.0, 200.0);
        assert_eq!(
            a,
            portable.cast(&o, &d, 0.0, 200.0),
            "random ray {i} from {o:?} along {d:?}: the kernels disagree"
        );
        hits += usize::from(a.is_some());
    }
    assert!(
        (20_000..99_000).contains(&hits),
        "expected a mix of hits and misses among the random rays, got {hits} of 100000"
    );
    eprintln!(
        "AVX2 kernel {}: {} sweep rays and 100000 random rays ({hits} hits) agree",
        if fast.uses_avx2() {
            "on"
        } else {
            "off (this CPU has no AVX2: both sides portable)"
        },
        rays.len()
    );
}
