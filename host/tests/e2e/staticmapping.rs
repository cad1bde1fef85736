//! The StaticMapping-style plugin on the simulator's own data: its point-to-plane ICP on
//! real sweeps against ground truth, and the plugin as the host runs it.

// M2DP on S3's sweeps: same place, the lane beside, elsewhere.
mod m2dp;

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use sim::sensors::{LidarScan, Message};
use sim::{SensorSet, SimConfig, Simulation};
use staticmapping::config::{IcpConfig, InputConfig};
use staticmapping::icp::{Reference, align};
use staticmapping::input::{deskew, filter};
use vinebench::runner::worker::plugin_point;

fn lidar_only() -> SensorSet {
    SensorSet {
        lidar: true,
        ..SensorSet::default()
    }
}

/// The sweeps of a scenario from `from_s` to `to_s`.
fn sweeps(sim: &Simulation, from_s: f64, to_s: f64) -> Vec<LidarScan> {
    let (a, b) = ((from_s * 1e9) as i64, (to_s * 1e9) as i64);
    sim.stream(lidar_only())
        .filter_map(|m| match m {
            Message::Lidar(s) if s.stamp_ns >= a => Some(s),
            _ => None,
        })
        .take_while(|s| s.stamp_ns <= b)
        .collect()
}

fn cloud(scan: &LidarScan, cfg: &InputConfig, seed: u64) -> Vec<Vector3<f64>> {
    let points: Vec<_> = scan.points.iter().map(plugin_point).collect();
    let sweep = filter(
        scan.stamp_ns,
        &points,
        cfg,
        &mut ChaCha8Rng::seed_from_u64(seed),
    );
    deskew(&sweep, None, scan.sweep_ns as f64 * 1e-9)
}

fn pose_error(a: &Isometry3<f64>, b: &Isometry3<f64>) -> (f64, f64) {
    let d = a.inverse() * b;
    (d.translation.vector.norm(), d.rotation.angle().to_degrees())
}

/// Guards the front end's matcher: a vineyard sweep (S0, mid-row, StaticMapping's input
/// filter) moved by a known transform — its points sampled afresh, as the next sweep's would
/// be — is brought back onto the first by the libpointmatcher-style ICP from a guess 0.25 m
/// and 1.4° off, with both the default 4.5 m and the vineyard 1 m minimum range.
#[test]
fn icp_recovers_a_known_transform_on_a_simulated_sweep() {
    let sim = Simulation::new(&SimConfig::default(), "s0", 0).expect("S0 builds");
    let scan = &sweeps(&sim, 20.0, 20.0)[0];
    let truth = Isometry3::from_parts(
        Translation3::new(0.5, 0.05, 0.01),
        UnitQuaternion::from_euler_angles(0.004, -0.003, 0.03),
    );
    let guess = truth
        * Isometry3::from_parts(
            Translation3::new(0.2, -0.15, 0.03),
            UnitQuaternion::from_euler_angles(0.005, 0.0, 0.02),
        );
    for min_range_m in [4.5, 1.0] {
        let cfg = InputConfig {
            min_range_m,
            ..InputConfig::default()
        };
        let icp = IcpConfig::default();
        let reference = Reference::new(&cloud(scan, &cfg, 1), icp.knn_normal);
        // The same surfaces, sampled with another seed, seen from `truth`.
        let reading: Vec<_> = cloud(scan, &cfg, 2)
            .iter()
            .map(|p| (truth.inverse() * nalgebra::Point3::from(*p)).coords)
            .collect();
        let (gm, gdeg) = pose_error(&guess, &truth);
        let r = align(&reading, &reference, &guess, &icp).expect("aligned");
        let (m, deg) = pose_error(&r.reference_from_reading, &truth);
        eprintln!(
            "min range {min_range_m} m: {} reading, {} reference points; guess off {gm:.3} m {gdeg:.3}°, result off {m:.4} m {deg:.4}° after {} iterations, score {:.3}",
            reading.len(),
            reference.len(),
            r.iterations,
            r.score
        );
        assert!(
            m < 0.02 && deg < 0.15,
            "min range {min_range_m} m: result off {m:.4} m {deg:.4}°"
        );
        assert!(r.score > 0.7, "score {:.3}", r.score);
    }
}

/// S3's route up to here: the first loop closures come at 69 s, when the robot drives back
/// through the lane beside its first.
const S3_LOOP_TEST_S: f64 = 80.0;

/// Guards loop closure end to end: the plugin, loaded from its `.so` by the host, on S3 to
/// 80 s with the vineyard minimum range (1 m). M2DP proposes candidates among the submaps
/// 25 m around, ICP verifies them, and agreeing edges enter the graph: there must be some,
/// each with its two stamps and its measured relative pose, which the host judges against
/// ground truth. They join the lane driven back to the one beside it, 3-4 m apart in
/// opposite directions, and every measured relative pose must be within the host's 0.5 m
/// and 10° of the truth. With StaticMapping's own 4.5 m minimum range no verification
/// scores 0.75 on S3 (measured, the whole route): no loop.
#[test]
fn loops_are_verified_and_added_in_s3() {
    let dir = tempfile::tempdir().expect("temp dir");
    let max_time = S3_LOOP_TEST_S.to_string();
    let run = crate::common::run_with(
        dir.path(),
        "s3",
        "staticmapping",
        "loops",
        "timing_json = \"build-timing.json\"\n[input]\nmin_range_m = 1.0\n",
        &["--max-time", &max_time],
    );
    let accepted = crate::common::loop_events(&run, "loop_closure_accepted");
    let report = crate::common::json(&run.join("build-timing.json"));
    eprintln!(
        "staticmapping s3 to {S3_LOOP_TEST_S} s: ATE {:.3} m, {} loop edges accepted; build {report}",
        crate::common::ate(&run, "estimate.tum"),
        accepted.len()
    );
    assert!(
        !accepted.is_empty(),
        "no loop closure accepted in S3: {}",
        crate::common::json(&run.join("events.json"))
    );
    for event in &accepted {
        let error = event.relative_error_m.unwrap_or(f64::INFINITY);
        assert!(
            event.stamps_ns.is_some() && error < 0.5 && event.true_loop == Some(true),
            "every accepted loop carries its stamps and a relative pose true to ground truth: {event:?}"
        );
    }
    let loops = &crate::common::json(&run.join("metrics.json"))["loops"];
    assert_eq!(
        loops["accepted"].as_u64(),
        Some(accepted.len() as u64),
        "{loops}"
    );
    assert_eq!(loops["accepted_false"].as_u64(), Some(0), "{loops}");
    assert_eq!(
        report["loop_edges_added"].as_u64(),
        Some(accepted.len() as u64),
        "one event per edge added to the graph: {report}"
    );
    let ate = crate::common::ate(&run, "estimate.tum");
    assert!(ate.is_finite() && ate < 1.0, "ATE {ate:.3} m");
}
