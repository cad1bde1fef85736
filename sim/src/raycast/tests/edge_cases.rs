//! Rays that graze, start inside, are clipped, or meet nothing.

use nalgebra::{Point3, Vector3};

use super::{grid, rng, soup};
use crate::raycast::{BruteForce, Bvh, Hit, ParryCaster, RayCaster};
use crate::world::{Material, Mesh};

fn one_triangle() -> Mesh {
    let mut mesh = Mesh::new();
    let a = mesh.push_vertex(Point3::new(0.0, 0.0, 0.0));
    let b = mesh.push_vertex(Point3::new(1.0, 0.0, 0.0));
    let c = mesh.push_vertex(Point3::new(0.0, 1.0, 0.0));
    mesh.push_triangle([a, b, c], Material::Leaf);
    mesh
}

fn casters(mesh: &Mesh) -> Vec<Box<dyn RayCaster>> {
    vec![
        Box::new(Bvh::build(mesh)),
        Box::new(BruteForce::build(mesh)),
        Box::new(ParryCaster::build(mesh)),
    ]
}

#[test]
fn ray_parallel_to_triangle_misses() {
    let mesh = one_triangle();
    for caster in casters(&mesh) {
        // In the plane of the triangle, straight across it, and just above it.
        for z in [0.0, 0.01] {
            let hit = caster.cast(&Point3::new(-1.0, 0.2, z), &Vector3::x(), 0.0, 10.0);
            assert_eq!(
                hit, None,
                "{caster:?}: expected no hit parallel to the triangle at z={z}"
            );
        }
    }
}

#[test]
fn ray_from_inside_scene_bounds() {
    let mesh = grid(20);
    let bvh = Bvh::build(&mesh);
    // Origin inside the (flat) bounds, on the ground itself: only t_min keeps it off.
    let origin = Point3::new(0.25, 0.25, 0.0);
    let hit = bvh.cast(&origin, &-Vector3::z(), 0.0, 1.0);
    assert!(
        hit.is_some_and(|h| h.t.abs() < 1e-6),
        "expected a hit at t = 0 from a point on the ground, got {hit:?}"
    );
    assert_eq!(
        bvh.cast(&origin, &-Vector3::z(), 0.01, 1.0),
        None,
        "expected nothing beyond t_min = 0.01 below the ground plane"
    );
    // Inside a soup's bounds: the hit is the brute-force one.
    let mesh = soup(&mut rng(5), 4000, 2.0, 0.6);
    let (bvh, brute) = (Bvh::build(&mesh), BruteForce::build(&mesh));
    let origin = Point3::origin();
    for dir in [
        Vector3::x(),
        Vector3::y(),
        -Vector3::z(),
        Vector3::new(1.0, 1.0, 1.0).normalize(),
    ] {
        let expected = brute.cast(&origin, &dir, 0.0, 100.0);
        assert!(
            expected.is_some(),
            "expected the dense soup to be hit along {dir:?}"
        );
        assert_eq!(
            bvh.cast(&origin, &dir, 0.0, 100.0),
            expected,
            "expected the brute-force hit along {dir:?}"
        );
    }
}

#[test]
fn t_min_and_t_max_are_respected() {
    // Two parallel planes, at z = -1 and z = -3 below the origin.
    let mut mesh = grid(4);
    let mut lower = grid(4);
    lower.vertices.iter_mut().for_each(|p| p.z = -2.0);
    mesh.append(&lower);
    for caster in casters(&mesh) {
        let cast =
            |t_min, t_max| caster.cast(&Point3::new(0.3, 0.1, 1.0), &-Vector3::z(), t_min, t_max);
        let t_of = |h: Option<Hit>| h.map(|h| h.t);
        let near = |h: Option<Hit>, t: f32| h.is_some_and(|h| (h.t - t).abs() < 1e-5);
        assert!(
            near(cast(0.0, 10.0), 1.0),
            "{caster:?}: expected the upper plane at 1 m, got {:?}",
            t_of(cast(0.0, 10.0))
        );
        assert!(
            near(cast(1.5, 10.0), 3.0),
            "{caster:?}: expected the lower plane at 3 m past t_min 1.5"
        );
        assert_eq!(
            cast(0.0, 0.5),
            None,
            "{caster:?}: expected nothing before t_max 0.5"
        );
        assert_eq!(
            cast(1.5, 2.5),
            None,
            "{caster:?}: expected nothing between the planes"
        );
        assert_eq!(
            cast(2.0, 1.0),
            None,
            "{caster:?}: expected nothing for an empty interval"
        );
    }
    // Both ends inclusive for the exact casters.
    let bvh = Bvh::build(&mesh);
    let d = -Vector3::z();
    let o = Point3::new(0.3, 0.1, 1.0);
    assert!(
        bvh.cast(&o, &d, 1.0, 1.0).is_some(),
        "expected a hit at t_min = t_max = 1"
    );
}

#[test]
fn empty_mesh_has_no_hit() {
    let mesh = Mesh::new();
    for caster in casters(&mesh) {
        let hit = caster.cast(&Point3::origin(), &Vector3::x(), 0.0, f32::INFINITY);
        assert_eq!(hit, None, "{caster:?}: expected no hit in an empty mesh");
        let mut out = [Some(Hit {
            t: 1.0,
            triangle: 0,
        }); 2];
        caster.cast_fan(
            &Point3::origin(),
            &[Vector3::x(), Vector3::y()],
            0.0,
            1.0,
            &mut out,
        );
        assert_eq!(
            out,
            [None, None],
            "{caster:?}: expected the fan cleared to misses"
        );
    }
    assert_eq!(
        Bvh::build(&mesh).node_count(),
        0,
        "expected no node for an empty mesh"
    );
}

#[test]
fn degenerate_triangles_are_ignored() {
    let mut mesh = Mesh::new();
    let a = mesh.push_vertex(Point3::new(0.0, 0.0, 0.0));
    let b = mesh.push_vertex(Point3::new(1.0, 0.0, 0.0));
    let c = mesh.push_vertex(Point3::new(2.0, 0.0, 0.0));
    mesh.push_triangle([a, b, c], Material::Wire); // collinear
    mesh.push_triangle([a, a, b], Material::Wire); // repeated corner
    mesh.push_triangle([b, b, b], Material::Wire); // a point
    let bvh = Bvh::build(&mesh);
    assert_eq!(
        bvh.node_count(),
        0,
        "expected degenerate triangles left out of the tree"
    );
    for caster in casters(&mesh) {
        // Straight through the segment the triangles collapse to.
        let hit = caster.cast(&Point3::new(0.5, 0.0, 1.0), &-Vector3::z(), 0.0, 10.0);
        assert_eq!(
            hit, None,
            "{caster:?}: expected degenerate triangles never hit"
        );
    }
    // Mixed with a real triangle, the real one is found with its own index.
    let mut mixed = mesh.clone();
    mixed.append(&one_triangle());
    let hit = Bvh::build(&mixed).cast(&Point3::new(0.2, 0.2, 1.0), &-Vector3::z(), 0.0, 10.0);
    assert_eq!(
        hit.map(|h| h.triangle),
        Some(3),
        "expected the real triangle, index 3"
    );
}
