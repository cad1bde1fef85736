//! The pictures of a run's false loops, wrong joins and a sample of its true loops, made
//! again into the run folder so that the report can show the two places a system joined
//! as it saw them (`frames/`, listed in `frames.json`):
//! - for a run that took the camera, the two colour frames it was given, and where its loop
//!   event carried `loop_matches`, the two side by side with the matched keypoints joined;
//! - for a run that took the lidar, the two sweeps' top views overlaid, the later one placed
//!   at the estimate's relative pose and then at ground truth's: a false join shows as two
//!   scans that agree under the estimate and not under the truth.
//!
//! The simulator is deterministic: from the run's `world.toml`, scenario and seed,
//! `sim::Simulation::rgbd_frame_at` gives the very frame the stream gave at a stamp, noise
//! included, and `lidar_sweep_at` the sweep without its range noise, without keeping
//! anything during the run. Only for runs whose data came from the simulation (a
//! `--dataset` replay's data are the recording's, which this does not read).

use std::path::Path;

use anyhow::Context as _;
use eval::plot::{Chart, Mark, Rgb, Swatch};
use nalgebra::{Isometry3, Point3};
use serde::Deserialize;

use crate::results::{FramePair, Frames, Joins, JudgedEvent, PairKind, RunFolder, files};

/// True loops drawn per run, beside every false one: a sample to compare against.
const TRUE_SAMPLE: usize = 2;
/// A sweep's points drawn in its top view: those above the ground (base frame, m) and
/// within this horizontal range of the sensor (m).
const SCAN_MIN_HEIGHT_M: f32 = 0.25;
const SCAN_MAX_RANGE_M: f32 = 25.0;
/// A later sweep's point overlaps the earlier sweep where one of its points is this near (m).
const OVERLAP_M: f64 = 0.2;
/// The estimate's pose at a stamp is its pose nearest in time, if this near (s).
const ESTIMATE_NEAREST_S: f64 = 0.2;
const LATER: Rgb = [230, 110, 20];
const EARLIER: Rgb = [30, 90, 200];
/// Colours the matches cycle through, so that crossing lines stay apart.
const MATCH_COLOURS: [Rgb; 6] = [
    [255, 60, 60],
    [60, 220, 60],
    [60, 140, 255],
    [255, 220, 0],
    [255, 0, 255],
    [0, 230, 230],
];

/// What `run.toml` says that decides the frames.
#[derive(Debug, Deserialize)]
struct RunToml {
    scenario: String,
    seed: u64,
    plugin: PluginToml,
}

#[derive(Debug, Deserialize)]
struct PluginToml {
    #[serde(default)]
    sensors: Vec<String>,
}

/// A pair worth drawing.
#[derive(Debug, Clone, PartialEq)]
struct Wanted {
    kind: PairKind,
    index: usize,
    /// Later, then earlier.
    stamps: [i64; 2],
    /// The system's matched keypoints, `[u, v]` later then earlier.
    matches: Option<Vec<[f32; 4]>>,
    /// The system's own measured `earlier_from_later` (a loop's `loop_relative_pose`).
    relative: Option<Isometry3<f64>>,
}

/// The pairs worth drawing: every false stamped loop, every wrong join, the first
/// [`TRUE_SAMPLE`] true stamped loops.
fn wanted(judged: &[JudgedEvent], joins: &Joins) -> Vec<Wanted> {
    let mut out = Vec::new();
    let mut true_drawn = 0;
    for (i, j) in judged.iter().enumerate() {
        let (Some(stamps), Some(verdict)) = (j.event.loop_stamps_ns, j.true_loop) else {
            continue;
        };
        let kind = if !verdict && j.event.kind == plugin_api::EventKind::LoopClosureAccepted {
            PairKind::FalseLoop
        } else if verdict && true_drawn < TRUE_SAMPLE {
            true_drawn += 1;
            PairKind::TrueLoop
        } else {
            continue;
        };
        out.push(Wanted {
            kind,
            index: i,
            stamps,
            matches: j.event.matches().map(<[_]>::to_vec),
            relative: j.event.relative_pose(),
        });
    }
    for (i, e) in joins.report.wrong_joins.iter().enumerate() {
        out.push(Wanted {
            kind: PairKind::WrongJoin,
            index: i,
            stamps: e.pair_s.map(|s| (s * 1e9).round() as i64),
            matches: None,
            relative: None,
        });
    }
    out
}

/// Renders the pictures of `run`'s loops and joins into `frames/` and writes
/// `frames.json`; does nothing for a run with neither camera nor lidar, without anything
/// to draw, or fed from a recording.
pub fn write_frames(run: &RunFolder, judged: &[JudgedEvent], joins: &Joins) -> anyhow::Result<()> {
    let wanted = wanted(judged, joins);
    if wanted.is_empty() || !run.has(files::WORLD) {
        return Ok(());
    }
    let Some(text) = run.read_run_toml() else {
        return Ok(());
    };
    let run_toml: RunToml = toml::from_str(&text)
        .with_context(|| format!("{}: unreadable", run.path(files::RUN).display()))?;
    let took = |s: &str| run_toml.plugin.sensors.iter().any(|x| x == s);
    let (camera, lidar) = (took("rgbd"), took("lidar"));
    if !camera && !lidar {
        return Ok(());
    }
    if let Some(timing) = run.read_timing()?
        && timing.source == "dataset"
    {
        return Ok(());
    }
    let world_path = run.path(files::WORLD);
    let config = sim::SimConfig::from_file(&world_path)
        .with_context(|| format!("{}: the run's world", world_path.display()))?;
    let simulation = sim::Simulation::new(&config, &run_toml.scenario, run_toml.seed)
        .with_context(|| format!("rebuilding {} for its frames", run_toml.scenario))?;
    // The final trajectory places the sweeps of a wrong join (and of a loop that came
    // without its relative pose); none: only ground truth's panel.
    let estimate = if lidar {
        run.read_estimate().ok()
    } else {
        None
    };
    let dir = run.path(files::FRAMES_DIR);
    std::fs::create_dir_all(&dir).with_context(|| dir.display().to_string())?;
    let mut frames = Frames::default();
    for w in wanted {
        let name = match w.kind {
            PairKind::FalseLoop => "false-loop",
            PairKind::TrueLoop => "true-loop",
            PairKind::WrongJoin => "wrong-join",
        };
        let stem = format!("{name}-{}", w.index);
        let relative = |file: String| format!("{}/{file}", files::FRAMES_DIR);
        let mut pair = FramePair {
            kind: w.kind,
            index: w.index,
            stamps_ns: w.stamps,
            files: Vec::new(),
            matches: None,
            matched_surfaces: std::collections::BTreeMap::new(),
            scans: Vec::new(),
            scan_overlap: Vec::new(),
        };
        if camera {
            let later = simulation.rgbd_frame_at(w.stamps[0]);
            let earlier = simulation.rgbd_frame_at(w.stamps[1]);
            if let (Some(later), Some(earlier)) = (later, earlier) {
                for (frame, which) in [(&later, "later"), (&earlier, "earlier")] {
                    let file = format!("{stem}-{which}.png");
                    sim::camera::save_rgb_png(&dir.join(&file), &frame.image)
                        .with_context(|| dir.join(&file).display().to_string())?;
                    pair.files.push(relative(file));
                }
                pair.stamps_ns = [later.stamp_ns, earlier.stamp_ns];
                if let Some(matches) = &w.matches {
                    let file = format!("{stem}-matches.png");
                    draw_matches(&dir.join(&file), &later.image, &earlier.image, matches)?;
                    pair.matches = Some(relative(file));
                    pair.matched_surfaces =
                        matched_surfaces(&simulation, [later.stamp_ns, earlier.stamp_ns], matches);
                }
            }
        }
        if lidar
            && let (Some(later), Some(earlier)) = (
                simulation.lidar_sweep_at(w.stamps[0]),
                simulation.lidar_sweep_at(w.stamps[1]),
            )
        {
            let truth = simulation.trajectory.pose(earlier.stamp_ns).inverse()
                * simulation.trajectory.pose(later.stamp_ns);
            let estimated = w.relative.or_else(|| {
                let e = estimate.as_ref()?;
                Some(nearest(e, earlier.stamp_ns)?.inverse() * nearest(e, later.stamp_ns)?)
            });
            let base_from_lidar = config.sensors.lidar.mount.base_from_sensor();
            let placements = [
                (estimated, "estimate", "the estimate's"),
                (Some(truth), "truth", "ground truth's"),
            ];
            for (placement, which, whose) in placements {
                let Some(earlier_from_later) = placement else {
                    continue;
                };
                let file = format!("{stem}-scans-{which}.png");
                let title = format!(
                    "{name} #{}: {:.1} s on {:.1} s, at {whose} relative pose",
                    w.index,
                    later.stamp_ns as f64 * 1e-9,
                    earlier.stamp_ns as f64 * 1e-9
                );
                let [later_xy, earlier_xy] = [
                    top_view_points(&later, &(earlier_from_later * base_from_lidar)),
                    top_view_points(&earlier, &base_from_lidar),
                ];
                pair.scan_overlap.push(overlap(&later_xy, &earlier_xy));
                draw_scans(&dir.join(&file), &title, [later_xy, earlier_xy])?;
                pair.scans.push(relative(file));
            }
            if !camera {
                pair.stamps_ns = [later.stamp_ns, earlier.stamp_ns];
            }
        }
        if !pair.files.is_empty() || !pair.scans.is_empty() {
            frames.pairs.push(pair);
        }
    }
    run.write_frames(&frames)
}

/// What each match's two keypoints lie on, counted by `"later/earlier"` surface pair: the
/// first surface on the colour camera's ray through each keypoint, in the frames at
/// `stamps_ns` (later, earlier).
fn matched_surfaces(
    simulation: &sim::Simulation,
    stamps_ns: [i64; 2],
    matches: &[[f32; 4]],
) -> std::collections::BTreeMap<String, usize> {
    let mut counts = std::collections::BTreeMap::new();
    for m in matches {
        let [later, earlier] =
            [(stamps_ns[0], m[0], m[1]), (stamps_ns[1], m[2], m[3])].map(|(stamp, u, v)| {
                simulation
                    .surface_at_pixel(stamp, f64::from(u), f64::from(v))
                    .map_or("sky", sim::Surface::name)
            });
        *counts.entry(format!("{later}/{earlier}")).or_insert(0) += 1;
    }
    counts
}

/// The estimate's pose nearest `stamp_ns`, if within [`ESTIMATE_NEAREST_S`].
fn nearest(trajectory: &eval::Trajectory, stamp_ns: i64) -> Option<Isometry3<f64>> {
    let t = stamp_ns as f64 * 1e-9;
    let i = trajectory.stamps.partition_point(|&s| s < t);
    [i.checked_sub(1), Some(i)]
        .into_iter()
        .flatten()
        .filter(|&k| k < trajectory.len())
        .min_by(|&a, &b| {
            (trajectory.stamps[a] - t)
                .abs()
                .total_cmp(&(trajectory.stamps[b] - t).abs())
        })
        .filter(|&k| (trajectory.stamps[k] - t).abs() <= ESTIMATE_NEAREST_S)
        .map(|k| trajectory.poses[k])
}

/// A sweep's points from above in the earlier base frame (`earlier_from_lidar`), ground
/// and far points left out.
fn top_view_points(
    scan: &sim::sensors::LidarScan,
    earlier_from_lidar: &Isometry3<f64>,
) -> Vec<(f64, f64)> {
    scan.points
        .iter()
        .filter(|p| p.x.hypot(p.y) <= SCAN_MAX_RANGE_M)
        .map(|p| earlier_from_lidar * Point3::new(p.x, p.y, p.z).cast::<f64>())
        .filter(|p| p.z >= f64::from(SCAN_MIN_HEIGHT_M))
        .map(|p| (p.x, p.y))
        .collect()
}

/// The share of `later`'s points with one of `earlier`'s within [`OVERLAP_M`] (from above):
/// how well the two sweeps agree where they are placed. 0 for an empty sweep.
fn overlap(later: &[(f64, f64)], earlier: &[(f64, f64)]) -> f64 {
    let cell = |(x, y): (f64, f64)| {
        (
            (x / OVERLAP_M).floor() as i64,
            (y / OVERLAP_M).floor() as i64,
        )
    };
    let mut grid: std::collections::BTreeMap<(i64, i64), Vec<(f64, f64)>> =
        std::collections::BTreeMap::new();
    for &p in earlier {
        grid.entry(cell(p)).or_default().push(p);
    }
    let near = |p: (f64, f64)| {
        let (cx, cy) = cell(p);
        (-1..=1).any(|dx| {
            (-1..=1).any(|dy| {
                grid.get(&(cx + dx, cy + dy))
                    .is_some_and(|ps| ps.iter().any(|q| (q.0 - p.0).hypot(q.1 - p.1) <= OVERLAP_M))
            })
        })
    };
    if later.is_empty() {
        return 0.0;
    }
    later.iter().filter(|&&p| near(p)).count() as f64 / later.len() as f64
}

/// Two sweeps' top views, the later one orange, the earlier one blue.
fn draw_scans(path: &Path, title: &str, scans: [Vec<(f64, f64)>; 2]) -> anyhow::Result<()> {
    let mut chart = Chart::top_view(title);
    for (points, colour) in scans.into_iter().zip([LATER, EARLIER]) {
        chart.marks.push(Mark::Dots {
            points,
            color: colour,
            radius_px: 1,
        });
    }
    chart.legend = vec![
        (Swatch::Box(LATER), "later sweep".into()),
        (Swatch::Box(EARLIER), "earlier sweep".into()),
    ];
    chart
        .save(path, 700)
        .with_context(|| path.display().to_string())
}

/// The later and the earlier colour frame side by side, each match a line from its
/// keypoint in the one to its keypoint in the other, with a ring at both ends.
fn draw_matches(
    path: &Path,
    later: &sim::camera::RgbdImage,
    earlier: &sim::camera::RgbdImage,
    matches: &[[f32; 4]],
) -> anyhow::Result<()> {
    let (w, h) = (
        later.width + earlier.width,
        later.height.max(earlier.height),
    );
    let mut rgb = vec![0u8; 3 * w * h];
    for (image, x0) in [(later, 0), (earlier, later.width)] {
        for row in 0..image.height {
            let src = &image.rgb[3 * row * image.width..3 * (row + 1) * image.width];
            rgb[3 * (row * w + x0)..3 * (row * w + x0 + image.width)].copy_from_slice(src);
        }
    }
    let mut put = |x: i64, y: i64, c: Rgb| {
        if (0..w as i64).contains(&x) && (0..h as i64).contains(&y) {
            let i = 3 * (y as usize * w + x as usize);
            rgb[i..i + 3].copy_from_slice(&c);
        }
    };
    for (k, m) in matches.iter().enumerate() {
        let c = MATCH_COLOURS[k % MATCH_COLOURS.len()];
        let a = (f64::from(m[0]), f64::from(m[1]));
        let b = (f64::from(m[2]) + later.width as f64, f64::from(m[3]));
        let steps = ((b.0 - a.0).abs().max((b.1 - a.1).abs()).ceil() as i64).max(1);
        for s in 0..=steps {
            let t = s as f64 / steps as f64;
            put(
                (a.0 + t * (b.0 - a.0)).round() as i64,
                (a.1 + t * (b.1 - a.1)).round() as i64,
                c,
            );
        }
        for (x, y) in [a, b] {
            for d in 0..24 {
                let angle = std::f64::consts::TAU * f64::from(d) / 24.0;
                put(
                    (x + 3.0 * angle.cos()).round() as i64,
                    (y + 3.0 * angle.sin()).round() as i64,
                    c,
                );
            }
        }
    }
    let png = eval::plot::encode_png(w as u32, h as u32, &rgb)?;
    std::fs::write(path, png).with_context(|| path.display().to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Joins holding one wrong join of two stretches (seconds) and its closest pair.
    fn one_wrong_join(later_s: [f64; 2], earlier_s: [f64; 2], pair_s: [f64; 2]) -> Joins {
        let mut joins = Joins::default();
        joins.report.wrong_joins.push(eval::JoinEpisode {
            kind: eval::EpisodeKind::WrongJoin,
            later_s,
            earlier_s,
            travel_m: 5.0,
            estimate_distance_m: 0.1,
            truth_distance_m: 5.8,
            later_place: [0.0, 0.0],
            earlier_place: [5.8, 0.0],
            pair_s,
        });
        joins
    }

    #[test]
    fn every_false_loop_and_wrong_join_and_two_true_loops_are_wanted() {
        use plugin_api::{Event, EventKind};
        let judged_loop = |stamps: [i64; 2], verdict: bool| JudgedEvent {
            event: Event::loop_closure(stamps[0], EventKind::LoopClosureAccepted, stamps, "x"),
            true_loop: Some(verdict),
            judged_by: None,
            wrong_join: None,
            revisit: None,
            gt_distance_m: None,
            gt_heading_deg: None,
            relative_error_m: None,
            relative_error_deg: None,
            error_before_m: None,
            error_after_m: None,
        };
        let judged = vec![
            judged_loop([10, 1], true),
            judged_loop([20, 2], false),
            judged_loop([30, 3], true),
            judged_loop([40, 4], true),
        ];
        let joins = one_wrong_join([100.0, 110.0], [5.0, 15.0], [105.0, 10.0]);
        let w: Vec<_> = wanted(&judged, &joins)
            .into_iter()
            .map(|w| (w.kind, w.index, w.stamps))
            .collect();
        assert_eq!(
            w,
            [
                (PairKind::TrueLoop, 0, [10, 1]),
                (PairKind::FalseLoop, 1, [20, 2]),
                (PairKind::TrueLoop, 2, [30, 3]),
                (PairKind::WrongJoin, 0, [105_000_000_000, 10_000_000_000]),
            ]
        );
    }

    /// Two sweeps of the same points overlap wholly, shifted by more than the radius not
    /// at all, and half of them shifted: half.
    #[test]
    fn overlap_is_the_share_of_points_near_the_other_sweep() {
        let earlier: Vec<(f64, f64)> = (0..100).map(|i| (0.05 * f64::from(i), 1.0)).collect();
        assert_eq!(overlap(&earlier, &earlier), 1.0);
        let moved: Vec<_> = earlier.iter().map(|&(x, y)| (x, y + 0.5)).collect();
        assert_eq!(overlap(&moved, &earlier), 0.0);
        let half: Vec<_> = earlier
            .iter()
            .enumerate()
            .map(|(i, &(x, y))| {
                if i % 2 == 0 {
                    (x, y + 0.15)
                } else {
                    (x, y + 0.25)
                }
            })
            .collect();
        assert_eq!(overlap(&half, &earlier), 0.5);
        assert_eq!(overlap(&[], &earlier), 0.0);
    }

    /// Nothing is drawn, and nothing written, for a run without its world or with neither
    /// the camera nor the lidar.
    #[test]
    fn a_run_without_a_world_or_a_camera_or_lidar_gets_no_frames() {
        let dir = tempfile::tempdir().expect("tempdir");
        let run = RunFolder::new(dir.path());
        let joins = one_wrong_join([1.0, 2.0], [0.0, 0.5], [1.5, 0.2]);
        write_frames(&run, &[], &joins).expect("no world: nothing to do");
        std::fs::write(run.path(files::WORLD), "").expect("world");
        std::fs::write(
            run.path(files::RUN),
            "scenario = \"s0\"\nseed = 0\n[plugin]\nsensors = [\"wheel_odometry\", \"imu\", \"scan2d\"]\n",
        )
        .expect("run.toml");
        write_frames(&run, &[], &joins).expect("no camera, no lidar: nothing to do");
        assert!(!run.path(files::FRAMES).exists());
        assert!(!run.path(files::FRAMES_DIR).exists());
    }
}
