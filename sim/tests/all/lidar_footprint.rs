//! Beam divergence against the footprint's geometry: a beam swept across the vertical edge
//! of a panel in front of a wall gives mixed pixels exactly where its sampled footprint
//! straddles the edge, and where the two surfaces lie far apart, the echo its mode picks.

use nalgebra::{Point3, Vector3};
use sim::raycast::{Bvh, RayCaster as _};
use sim::sensors::lidar_footprint::{Footprint, ReturnMode};
use sim::world::{Material, Mesh};

/// A vertical rectangle at `x`, spanning `y0..y1` and z in ±5 m.
fn panel(mesh: &mut Mesh, x: f32, y0: f32, y1: f32, material: Material) {
    let v = [(y0, -5.0), (y1, -5.0), (y1, 5.0), (y0, 5.0)]
        .map(|(y, z)| mesh.push_vertex(Point3::new(x, y, z)));
    mesh.push_triangle([v[0], v[1], v[2]], material);
    mesh.push_triangle([v[0], v[2], v[3]], material);
}

/// What the beam along azimuth `a` (rad, elevation 0, from the origin) returns, for every
/// step of a sweep across the edge at azimuth 0: a panel at 3 m covers positive azimuths,
/// a wall at `wall_m` is behind it.
fn sweep(wall_m: f32, mode: ReturnMode) -> Vec<(f32, Option<f32>)> {
    let mut mesh = Mesh::new();
    panel(&mut mesh, 3.0, 0.0, 5.0, Material::Post);
    panel(&mut mesh, wall_m, -20.0, 20.0, Material::Post);
    let caster = Bvh::build(&mesh);
    // The paper's lidar's divergence as Velodyne states it for its VLS-128: 3.0 mrad along
    // the scan, 1.5 across.
    let footprint = Footprint {
        divergence_rad: [3e-3, 1.5e-3],
        echo_separation_m: 1.0,
        mode,
    };
    // Steps of 0.01 mrad from -6 to +6 mrad, each at the middle of its step.
    (0..1200)
        .map(|k| {
            let a = (-6.0 + 0.01 * (k as f32 + 0.5)) * 1e-3;
            let dir = Vector3::new(a.cos(), a.sin(), 0.0);
            let (o, t) = (Point3::origin(), (0.1, 100.0));
            let centre = caster.cast(&o, &dir, t.0, t.1);
            let r = footprint.beam_return(&caster, &mesh, &o, &dir, centre, t.0, t.1);
            (a, r.map(|r| r.range_m))
        })
        .collect()
}

/// The sub-rays across the scan lie at the footprint's centre and ±2/3 of its half width:
/// ±1 mrad. They straddle the edge for azimuths within ±1 mrad of it: 2 mrad of the 12
/// swept. With the wall 0.5 m behind the panel (within the 1 m echo separation) each of
/// those beams reports one point between the two surfaces.
#[test]
fn mixed_pixels_occur_where_the_footprint_straddles_an_edge() {
    let beams = sweep(3.5, ReturnMode::Strongest);
    let mixed: Vec<f32> = beams
        .iter()
        .filter(|(_, r)| r.is_some_and(|r| r > 3.001 && r < 3.499))
        .map(|(a, _)| *a)
        .collect();
    assert_eq!(mixed.len(), 200, "2 mrad of 12 in 0.01 mrad steps");
    let (lo, hi) = (mixed[0], mixed[mixed.len() - 1]);
    assert!(
        (lo + 1e-3).abs() < 2e-5 && (hi - 1e-3).abs() < 2e-5,
        "mixed from {lo} to {hi} rad"
    );
    // Outside the band every beam is on one surface, and no beam is lost.
    for (a, r) in &beams {
        let r = r.expect("every beam meets the panel or the wall");
        if *a < -1.01e-3 {
            assert!((r - 3.5).abs() < 0.01, "{a}: {r}");
        } else if *a > 1.01e-3 {
            assert!((r - 3.0).abs() < 0.01, "{a}: {r}");
        }
    }
    // Nearer the panel, more of the footprint (and more energy) on it: the mixed range
    // falls monotonically from the wall's to the panel's across the band.
    let ranges: Vec<f32> = beams.iter().filter_map(|(_, r)| *r).collect();
    assert!(ranges.windows(2).all(|w| w[1] <= w[0] + 1e-4), "monotone");
}

/// With the wall 3 m behind the panel the two echoes part: no point between them; the
/// strongest return is the panel's as soon as a third of the footprint is on it (nine times
/// the wall's energy per sub-ray at a third of the range), the last the wall's as long as a
/// third of the footprint sees it.
#[test]
fn parted_echoes_give_the_strongest_or_the_last() {
    for (mode, near_from, far_until) in [
        (ReturnMode::Strongest, -1e-3, -1e-3),
        (ReturnMode::Last, 1e-3, 1e-3),
    ] {
        for (a, r) in sweep(6.0, mode) {
            let r = r.expect("a return");
            assert!(
                (r - 3.0).abs() < 0.01 || (r - 6.0).abs() < 0.02,
                "{mode:?} {a}: {r} is on neither surface"
            );
            if a > near_from + 1e-5 {
                assert!((r - 3.0).abs() < 0.01, "{mode:?} {a}: {r}, the panel's");
            } else if a < far_until - 1e-5 {
                assert!((r - 6.0).abs() < 0.02, "{mode:?} {a}: {r}, the wall's");
            }
        }
    }
}

/// In the vineyard the footprints change the beams at edges only: a sweep with the
/// divergence differs from the thin rays' in some points (posts, leaves and wires in front
/// of what lies behind them) but not in most (the ground, the wall of leaves seen face on).
#[test]
fn in_the_vineyard_only_beams_at_edges_change() {
    use sim::sensors::Message;
    use sim::{SensorSet, SimConfig, Simulation};
    let thin = SimConfig::from_toml_str("profile = \"ideal\"\n", "ideal").expect("world");
    let mut wide = thin.clone();
    wide.sensors.lidar.beam_divergence_mrad = [3.0, 1.5];
    let first_sweep = |cfg: &SimConfig| {
        let sim = Simulation::new(cfg, "s0", 0).expect("simulation");
        let lidar = SensorSet {
            lidar: true,
            ..SensorSet::default()
        };
        sim.stream(lidar)
            .find_map(|m| match m {
                Message::Lidar(scan) => Some(scan.points),
                _ => None,
            })
            .expect("a sweep")
    };
    let (a, b) = (first_sweep(&thin), first_sweep(&wide));
    // A beam: its ring and its column's firing time (every column fires at its own).
    let key = |p: &sim::sensors::LidarPoint| (p.ring, p.time_s.to_bits());
    let thin_points: std::collections::BTreeMap<_, _> = a.iter().map(|p| (key(p), p)).collect();
    let changed = b
        .iter()
        .filter(|p| {
            thin_points
                .get(&key(p))
                .is_none_or(|q| (q.x, q.y, q.z) != (p.x, p.y, p.z))
        })
        .count();
    let share = changed as f64 / b.len() as f64;
    assert!(
        (0.005..0.5).contains(&share),
        "{changed} of {} points changed ({share:.3})",
        b.len()
    );
    let count_ratio = b.len() as f64 / a.len() as f64;
    assert!(
        (0.95..1.05).contains(&count_ratio),
        "{} vs {} points",
        b.len(),
        a.len()
    );
}
