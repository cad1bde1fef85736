//! The BVH against parry3d's TriMesh, an independent implementation.

use nalgebra::Vector3;

use super::{grid, point_in, rng, soup, unit_dir};
use crate::raycast::{Bvh, ParryCaster, RayCaster};

#[test]
fn bvh_matches_parry_on_random_scene() {
    let mut rng = rng(11);
    let mut mesh = grid(40);
    mesh.append(&soup(&mut rng, 4000, 8.0, 0.3));
    let bvh = Bvh::build(&mesh);
    let parry = ParryCaster::build(&mesh);
    let mut hits = 0;
    for i in 0..20_000 {
        let origin = point_in(&mut rng, -9.0, 9.0);
        // Half the rays look down-ish towards the ground, like a lidar.
        let mut dir = unit_dir(&mut rng);
        if i % 2 == 0 && dir.z > 0.0 {
            dir.z = -dir.z;
        }
        let got = bvh.cast(&origin, &dir, 0.05, 60.0);
        let expected = parry.cast(&origin, &dir, 0.05, 60.0);
        match (got, expected) {
            (Some(g), Some(e)) => {
                assert!(
                    (g.t - e.t).abs() < 1e-3,
                    "ray {i} from {origin:?} along {dir:?}: expected t = {} (parry), got {}",
                    e.t,
                    g.t
                );
                // Different triangles only where both are hit at the same range (shared edge).
                if g.triangle != e.triangle {
                    let other = bvh.cast(&origin, &dir, e.t - 1e-3, e.t + 1e-3);
                    assert!(
                        other.is_some(),
                        "ray {i}: expected parry's triangle {} to be at the BVH hit range too",
                        e.triangle
                    );
                }
                hits += 1;
            }
            (None, None) => {}
            _ => panic!(
                "ray {i} from {origin:?} along {dir:?}: expected parry's {expected:?}, got {got:?}"
            ),
        }
    }
    assert!(
        hits > 8_000,
        "expected most rays to hit, got {hits} of 20000"
    );
}

#[test]
fn straight_down_on_grid_hits_ground() {
    let mesh = grid(10);
    let bvh = Bvh::build(&mesh);
    let parry = ParryCaster::build(&mesh);
    let origin = nalgebra::Point3::new(0.3, 0.2, 2.0);
    let down = -Vector3::z();
    for caster in [&bvh as &dyn RayCaster, &parry] {
        let hit = caster.cast(&origin, &down, 0.0, 10.0);
        assert!(
            hit.is_some_and(|h| (h.t - 2.0).abs() < 1e-5),
            "{caster:?}: expected the ground 2 m below, got {hit:?}"
        );
    }
}
