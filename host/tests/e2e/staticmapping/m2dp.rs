//! M2DP (slam_common::place::m2dp) on the simulator's lidar sweeps of the first 100 s of S3, the
//! serpentine through the vineyard's lanes 3 m apart: how far apart the descriptors of sweeps taken at the same place
//! are, compared with sweeps from the same along-row position one lane over (the vineyard's
//! perceptual aliasing) and with sweeps from elsewhere. Printed as a Markdown table for the
//! range filter StaticMapping applies to its input ([4.5, 75] m) and for [1, 75] m.

use nalgebra::Vector3;
use sim::sensors::Message;
use sim::{SensorSet, SimConfig, Simulation};
use slam_common::place::m2dp::{Descriptor, M2dpConfig, descriptor};

/// The part of S3 streamed, s: two lanes, enough for every class of pair.
const ROUTE_S: f64 = 100.0;

/// Every `STRIDE`-th sweep is kept (0.5 s apart at 10 Hz, at most 0.25 m at 0.5 m/s).
const STRIDE: usize = 5;

/// The two range filters compared, metres: StaticMapping's and one that keeps the near rows.
const FILTERS: [(f64, f64); 2] = [(4.5, 75.0), (1.0, 75.0)];

/// Where a sweep was taken and its descriptor under each of [`FILTERS`].
#[derive(Debug)]
struct Sweep {
    stamp_ns: i64,
    x: f64,
    y: f64,
    yaw: f64,
    /// In a lane between two rows, driving along it.
    in_lane: bool,
    descriptors: Vec<Option<Descriptor>>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Class {
    SameLane,
    AliasedLane,
    Elsewhere,
}

const CLASSES: [(Class, &str); 3] = [
    (Class::SameLane, "same lane (< 0.5 m)"),
    (Class::AliasedLane, "aliased lane (±3 m, same along-row)"),
    (Class::Elsewhere, "elsewhere (> 10 m)"),
];

fn angle_between(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(std::f64::consts::TAU);
    d.min(std::f64::consts::TAU - d)
}

/// Rows run along the world x axis (checked on the trajectory by `in_lane`), lanes are
/// `row_spacing_m` apart in y.
fn classify(a: &Sweep, b: &Sweep) -> Option<Class> {
    let (dx, dy) = (b.x - a.x, b.y - a.y);
    let distance = dx.hypot(dy);
    if a.stamp_ns == b.stamp_ns {
        None
    } else if distance < 0.5 && angle_between(a.yaw, b.yaw) < 30f64.to_radians() {
        Some(Class::SameLane)
    } else if a.in_lane && b.in_lane && dx.abs() < 0.5 && (2.5..=3.5).contains(&dy.abs()) {
        Some(Class::AliasedLane)
    } else if distance > 10.0 {
        Some(Class::Elsewhere)
    } else {
        None
    }
}

fn median(sorted: &[f64]) -> f64 {
    let n = sorted.len();
    if n % 2 == 1 {
        sorted[n / 2]
    } else {
        0.5 * (sorted[n / 2 - 1] + sorted[n / 2])
    }
}

#[derive(Debug, Clone, Copy)]
struct Stats {
    mean: f64,
    median: f64,
    min: f64,
    max: f64,
}

fn stats(values: &mut [f64]) -> Stats {
    values.sort_by(f64::total_cmp);
    Stats {
        mean: values.iter().sum::<f64>() / values.len() as f64,
        median: median(values),
        min: values[0],
        max: values[values.len() - 1],
    }
}

/// Guards M2DP's usefulness for place recognition in a vineyard: on S3's sweeps, pairs of
/// sweeps taken within 0.5 m of each other have closer descriptors than pairs one lane
/// apart at the same along-row position and than pairs more than 10 m apart.
#[test]
fn m2dp_same_place_versus_adjacent_lane_in_s3() {
    let started = std::time::Instant::now();
    let sim = Simulation::new(&SimConfig::default(), "s3", 0).expect("S3 builds");
    let vineyard = &sim.config.vineyard;
    let cfg = M2dpConfig::default();
    let sensors = SensorSet {
        lidar: true,
        ..SensorSet::default()
    };

    let mut sweeps = Vec::new();
    let mut lane_ys = Vec::new();
    for (k, m) in sim.stream(sensors).enumerate() {
        let Message::Lidar(scan) = m else { continue };
        if scan.stamp_ns as f64 * 1e-9 > ROUTE_S {
            break;
        }
        if k % STRIDE != 0 {
            continue;
        }
        let pose = sim.trajectory.pose(scan.stamp_ns + scan.sweep_ns / 2);
        let (x, y) = (pose.translation.x, pose.translation.y);
        let yaw = pose.rotation.euler_angles().2;
        let lane = (0..vineyard.lanes())
            .map(|l| vineyard.lane_y(l))
            .min_by(|a, b| (a - y).abs().total_cmp(&(b - y).abs()))
            .expect("the vineyard has lanes");
        let along_rows = angle_between(yaw, 0.0).min(angle_between(yaw, std::f64::consts::PI))
            < 15f64.to_radians();
        let in_lane =
            (lane - y).abs() < 0.5 && along_rows && (0.0..=vineyard.row_length_m).contains(&x);
        if in_lane {
            lane_ys.push(lane);
        }
        let points: Vec<Vector3<f64>> = scan
            .points
            .iter()
            .map(|p| Vector3::new(p.x as f64, p.y as f64, p.z as f64))
            .collect();
        let descriptors = FILTERS
            .iter()
            .map(|&(lo, hi)| {
                let kept: Vec<Vector3<f64>> = points
                    .iter()
                    .filter(|p| (lo..=hi).contains(&p.norm()))
                    .copied()
                    .collect();
                descriptor(&kept, &cfg)
            })
            .collect();
        sweeps.push(Sweep {
            stamp_ns: scan.stamp_ns,
            x,
            y,
            yaw,
            in_lane,
            descriptors,
        });
    }
    lane_ys.sort_by(f64::total_cmp);
    lane_ys.dedup();
    println!(
        "S3: {} sweeps kept (every {STRIDE}th), {} of them in lanes at y = {lane_ys:?}; \
         streamed and described in {:.1} s",
        sweeps.len(),
        sweeps.iter().filter(|s| s.in_lane).count(),
        started.elapsed().as_secs_f64()
    );
    assert!(
        lane_ys.len() >= 2,
        "S3 should drive through two lanes along x by then, found lanes at {lane_ys:?}"
    );

    for (f, &(lo, hi)) in FILTERS.iter().enumerate() {
        let described = sweeps.iter().filter(|s| s.descriptors[f].is_some()).count();
        println!(
            "\nRange filter [{lo}, {hi}] m ({described} of {} sweeps described):\n",
            sweeps.len()
        );
        println!(
            "| class | pairs | distance mean | median | min | similarity mean | median | min | max |"
        );
        println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|");
        let mut medians = Vec::new();
        for (class, name) in CLASSES {
            let (mut distances, mut similarities) = (Vec::new(), Vec::new());
            for (i, a) in sweeps.iter().enumerate() {
                for b in &sweeps[i + 1..] {
                    if classify(a, b) != Some(class) {
                        continue;
                    }
                    if let (Some(da), Some(db)) = (&a.descriptors[f], &b.descriptors[f]) {
                        distances.push(da.distance(db));
                        similarities.push(da.similarity(db));
                    }
                }
            }
            assert!(
                !distances.is_empty(),
                "no pairs of class {name} with filter [{lo}, {hi}] m"
            );
            let pairs = distances.len();
            let d = stats(&mut distances);
            let s = stats(&mut similarities);
            println!(
                "| {name} | {pairs} | {:.4} | {:.4} | {:.4} | {:.4} | {:.4} | {:.4} | {:.4} |",
                d.mean, d.median, d.min, s.mean, s.median, s.min, s.max
            );
            medians.push(d.median);
        }
        let (same, aliased, elsewhere) = (medians[0], medians[1], medians[2]);
        assert!(
            same < aliased && same < elsewhere,
            "[{lo}, {hi}] m: median distance same lane {same:.4}, aliased lane {aliased:.4}, \
             elsewhere {elsewhere:.4}"
        );
    }
}
