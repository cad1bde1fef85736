//! Cross-check against evo itself (MichaelGrupp/evo, the tool researchers compare with):
//! seeded trajectory pairs (noise, drift, scale, time offset, missing poses, a denser
//! estimate) are written as TUM files, evaluated by `evo_ape` / `evo_rpe` (through
//! `tests/evo/run_evo.py`, which reads evo's `--save_results` zip) and by this crate;
//! the number of pairs must be equal and every statistic and every per-pair error must
//! agree within 1e-6 relative.
//!
//! Needs evo on PATH (and `python3` able to import numpy, e.g. evo's venv first on PATH;
//! `EVO_PYTHON` overrides the interpreter): without evo this test fails, telling to run
//! the README test command (`bash scripts/test.sh`), which installs it.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

use eval::{
    Alignment, ApeOptions, Association, DeltaUnit, Pairing, PoseRelation, RpeOptions, Statistics,
    Trajectory, evaluate_ape, evaluate_rpe, read_tum, write_tum,
};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

const RELATIVE_TOLERANCE: f64 = 1e-6;
/// Below this, values count as equal (e.g. 0 against 1e-16 after origin alignment).
const ABSOLUTE_FLOOR: f64 = 1e-12;

/// A vineyard-like ground truth: down a row, a headland turn, back the next row, with
/// gentle roll and pitch from uneven ground; `n` poses at `rate_hz` from `t0`.
fn reference(n: usize, rate_hz: f64, t0: f64) -> Trajectory {
    let mut stamps = Vec::with_capacity(n);
    let mut poses = Vec::with_capacity(n);
    for i in 0..n {
        let t = t0 + i as f64 / rate_hz;
        let s = 0.05 * t;
        let (x, y) = (18.0 * s.sin() + 0.3 * t, 3.0 * (0.5 * s).sin() + 2.0 * s);
        let (dx, dy) = (
            18.0 * 0.05 * s.cos() + 0.3,
            3.0 * 0.025 * (0.5 * s).cos() + 0.1,
        );
        let z = 0.1 * (0.7 * t).sin();
        let rotation = UnitQuaternion::from_euler_angles(
            0.02 * (1.3 * t).sin(),
            0.03 * (0.9 * t).cos(),
            dy.atan2(dx),
        );
        stamps.push(t);
        poses.push(Isometry3::from_parts(Translation3::new(x, y, z), rotation));
    }
    Trajectory::new(stamps, poses)
}

fn noisy(
    rng: &mut ChaCha8Rng,
    pose: &Isometry3<f64>,
    sigma_m: f64,
    sigma_rad: f64,
) -> Isometry3<f64> {
    let n = |rng: &mut ChaCha8Rng, s: f64| Normal::new(0.0, s).expect("valid sigma").sample(rng);
    let dp = Vector3::new(n(rng, sigma_m), n(rng, sigma_m), n(rng, sigma_m));
    let dr = Vector3::new(n(rng, sigma_rad), n(rng, sigma_rad), n(rng, sigma_rad));
    Isometry3::new(dp, Vector3::zeros()) * pose * Isometry3::new(Vector3::zeros(), dr)
}

/// A pair to check and the extra evo arguments (time offset) its evaluation needs.
struct Case {
    name: &'static str,
    reference: Trajectory,
    estimate: Trajectory,
    t_offset: f64,
}

fn cases() -> Vec<Case> {
    let mut rng = ChaCha8Rng::seed_from_u64(20240611);
    let frame = Isometry3::new(Vector3::new(4.0, -7.0, 1.5), Vector3::new(0.05, -0.1, 2.0));
    let mut cases = Vec::new();

    // Noise: same rate, stamps jittered by up to ±3 ms, 3 cm and 0.5° noise.
    let r = reference(1500, 20.0, 1000.0);
    let mut e = r.clone();
    for (t, p) in e.stamps.iter_mut().zip(&mut e.poses) {
        *t += rng.random_range(-0.003..0.003);
        *p = noisy(&mut rng, p, 0.03, 0.5f64.to_radians());
    }
    cases.push(Case {
        name: "noise",
        reference: r,
        estimate: e,
        t_offset: 0.0,
    });

    // Drift: odometry integrating noisy increments, expressed in another world frame.
    let r = reference(2000, 20.0, 0.0);
    let mut poses = vec![frame * r.poses[0]];
    for w in r.poses.windows(2) {
        let step = noisy(&mut rng, &(w[0].inverse() * w[1]), 0.002, 0.001);
        poses.push(poses.last().expect("non-empty") * step);
    }
    let e = Trajectory::new(r.stamps.clone(), poses);
    cases.push(Case {
        name: "drift",
        reference: r,
        estimate: e,
        t_offset: 0.0,
    });

    // Scale: 0.8× the size (monocular-like) in another frame, with noise.
    let r = reference(1200, 10.0, 50.0);
    let poses = r
        .poses
        .iter()
        .map(|p| {
            let mut q = frame * *p;
            q.translation.vector *= 0.8;
            noisy(&mut rng, &q, 0.02, 0.2f64.to_radians())
        })
        .collect();
    let e = Trajectory::new(r.stamps.clone(), poses);
    cases.push(Case {
        name: "scale",
        reference: r,
        estimate: e,
        t_offset: 0.0,
    });

    // Time offset: 100 Hz reference, 15 Hz estimate whose clock runs 0.25 s ahead.
    let r = reference(9000, 100.0, 0.0);
    let dense = reference(9000 * 3, 300.0, 0.0);
    let mut e = Trajectory::default();
    for k in (1..dense.len()).step_by(20) {
        e.stamps.push(dense.stamps[k] + 0.25);
        e.poses.push(noisy(&mut rng, &dense.poses[k], 0.05, 0.01));
    }
    cases.push(Case {
        name: "time-offset",
        reference: r,
        estimate: e,
        t_offset: -0.25,
    });

    // Missing poses: 30 % dropped at random and a 10 s outage.
    let r = reference(3000, 30.0, 10.0);
    let mut e = Trajectory::default();
    for (t, p) in r.stamps.iter().zip(&r.poses) {
        if rng.random::<f64>() < 0.3 || (40.0..50.0).contains(t) {
            continue;
        }
        e.stamps.push(t + rng.random_range(-0.004..0.004));
        e.poses
            .push(noisy(&mut rng, &(frame * p), 0.04, 0.3f64.to_radians()));
    }
    cases.push(Case {
        name: "missing",
        reference: r,
        estimate: e,
        t_offset: 0.0,
    });

    // Denser estimate than reference (the estimate is the longer one) with an offset that
    // leaves the shifted stamps 2.3 ms off the reference's, so interpolation matters.
    let r = reference(600, 10.0, 0.0);
    let dense = reference(12000, 200.0, 0.0);
    let mut e = dense.clone();
    for (t, p) in e.stamps.iter_mut().zip(&mut e.poses) {
        *t += 0.0523;
        *p = noisy(&mut rng, p, 0.01, 0.005);
    }
    cases.push(Case {
        name: "dense-estimate",
        reference: r,
        estimate: e,
        t_offset: -0.05,
    });
    cases
}

/// One evaluation setting, in evo's arguments and ours.
struct Setting {
    name: &'static str,
    evo_args: &'static [&'static str],
    kind: Kind,
}

enum Kind {
    Ape(ApeOptions),
    Rpe(RpeOptions),
}

fn ape(alignment: Alignment, relation: PoseRelation) -> Kind {
    Kind::Ape(ApeOptions {
        alignment,
        relation,
        ..Default::default()
    })
}

fn rpe(delta: f64, unit: DeltaUnit, all_pairs: bool, relation: PoseRelation) -> Kind {
    Kind::Rpe(RpeOptions {
        delta,
        unit,
        all_pairs,
        relation,
        ..Default::default()
    })
}

fn settings() -> Vec<Setting> {
    use Alignment as A;
    use PoseRelation as R;
    let interpolated = ApeOptions {
        alignment: A::Se3,
        pairing: Pairing::ByStamp(Association {
            interpolate: true,
            ..Default::default()
        }),
        ..Default::default()
    };
    let first_100 = ApeOptions {
        alignment: A::Se3,
        n_to_align: Some(100),
        ..Default::default()
    };
    let rpe_sim3 = RpeOptions {
        unit: DeltaUnit::Metres,
        alignment: A::Sim3,
        ..Default::default()
    };
    vec![
        Setting {
            name: "ape none",
            evo_args: &[],
            kind: ape(A::None, R::Translation),
        },
        Setting {
            name: "ape origin",
            evo_args: &["--align_origin"],
            kind: ape(A::Origin, R::Translation),
        },
        Setting {
            name: "ape se3",
            evo_args: &["-a"],
            kind: ape(A::Se3, R::Translation),
        },
        Setting {
            name: "ape sim3",
            evo_args: &["-as"],
            kind: ape(A::Sim3, R::Translation),
        },
        Setting {
            name: "ape scale",
            evo_args: &["-s"],
            kind: ape(A::Scale, R::Translation),
        },
        Setting {
            name: "ape se3 angle_deg",
            evo_args: &["-a", "-r", "angle_deg"],
            kind: ape(A::Se3, R::AngleDeg),
        },
        Setting {
            name: "ape sim3 full",
            evo_args: &["-as", "-r", "full"],
            kind: ape(A::Sim3, R::Full),
        },
        Setting {
            name: "ape se3 first 100",
            evo_args: &["-a", "--n_to_align", "100"],
            kind: Kind::Ape(first_100),
        },
        Setting {
            name: "ape se3 interpolated",
            evo_args: &["-a", "--sync_method", "interpolation"],
            kind: Kind::Ape(interpolated),
        },
        Setting {
            name: "rpe 1 f",
            evo_args: &["--delta", "1", "--delta_unit", "f"],
            kind: rpe(1.0, DeltaUnit::Frames, false, R::Translation),
        },
        Setting {
            name: "rpe 1 m",
            evo_args: &["--delta", "1", "--delta_unit", "m"],
            kind: rpe(1.0, DeltaUnit::Metres, false, R::Translation),
        },
        Setting {
            name: "rpe 1 m sim3",
            evo_args: &["--delta", "1", "--delta_unit", "m", "-as"],
            kind: Kind::Rpe(rpe_sim3),
        },
        Setting {
            name: "rpe 5 f all angle_rad",
            evo_args: &[
                "--delta",
                "5",
                "--delta_unit",
                "f",
                "--all_pairs",
                "-r",
                "angle_rad",
            ],
            kind: rpe(5.0, DeltaUnit::Frames, true, R::AngleRad),
        },
        Setting {
            name: "rpe 2 m all",
            evo_args: &["--delta", "2", "--delta_unit", "m", "--all_pairs"],
            kind: rpe(2.0, DeltaUnit::Metres, true, R::Translation),
        },
    ]
}

/// evo's statistics and per-pair errors.
#[derive(Debug, serde::Deserialize)]
struct EvoResult {
    stats: EvoStats,
    errors: Vec<f64>,
}

#[derive(Debug, serde::Deserialize)]
struct EvoStats {
    rmse: f64,
    mean: f64,
    median: f64,
    std: f64,
    min: f64,
    max: f64,
    sse: f64,
}

fn run_evo(
    tool: &str,
    reference: &Path,
    estimate: &Path,
    t_offset: f64,
    args: &[&str],
) -> Result<EvoResult, String> {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/evo/run_evo.py");
    let python = std::env::var("EVO_PYTHON").unwrap_or_else(|_| "python3".into());
    let mut command = Command::new(python);
    command
        .arg(&script)
        .arg(tool)
        .arg("tum")
        .arg(reference)
        .arg(estimate)
        .args(args);
    if t_offset != 0.0 {
        command.arg("--t_offset").arg(t_offset.to_string());
    }
    let output = command
        .output()
        .map_err(|e| format!("cannot run {}: {e}", script.display()))?;
    if !output.status.success() {
        return Err(String::from_utf8_lossy(&output.stderr).into_owned());
    }
    serde_json::from_slice(&output.stdout)
        .map_err(|e| format!("unreadable output of run_evo.py: {e}"))
}

fn close(ours: f64, evo: f64) -> bool {
    (ours - evo).abs() <= RELATIVE_TOLERANCE * ours.abs().max(evo.abs())
        || (ours - evo).abs() <= ABSOLUTE_FLOOR
}

/// Mismatches between our result and evo's, as readable lines.
fn compare(label: &str, ours: &Statistics, errors: &[f64], evo: &EvoResult) -> Vec<String> {
    let mut problems = Vec::new();
    if ours.pairs != evo.errors.len() {
        problems.push(format!(
            "{label}: expected {} pairs like evo, got {}",
            evo.errors.len(),
            ours.pairs
        ));
        return problems;
    }
    let s = &evo.stats;
    for (name, a, b) in [
        ("rmse", ours.rmse, s.rmse),
        ("mean", ours.mean, s.mean),
        ("median", ours.median, s.median),
        ("std", ours.std, s.std),
        ("min", ours.min, s.min),
        ("max", ours.max, s.max),
        ("sse", ours.sse, s.sse),
    ] {
        if !close(a, b) {
            problems.push(format!(
                "{label}: expected {name} {b} like evo, got {a} (rel. diff {:.2e})",
                (a - b).abs() / b.abs()
            ));
        }
    }
    if let Some((i, (a, b))) = errors
        .iter()
        .zip(&evo.errors)
        .enumerate()
        .find(|(_, (a, b))| !close(**a, **b))
    {
        problems.push(format!(
            "{label}: expected error[{i}] = {b} like evo, got {a}"
        ));
    }
    problems
}

fn evo_available() -> Result<(), String> {
    match Command::new("evo_ape").arg("--help").output() {
        Ok(out) if out.status.success() => Ok(()),
        Ok(out) => Err(format!(
            "`evo_ape --help` failed: {}",
            String::from_utf8_lossy(&out.stderr)
        )),
        Err(e) => Err(format!("evo_ape is not on PATH ({e})")),
    }
}

#[test]
fn statistics_equal_evo_on_generated_pairs() {
    if let Err(why) = evo_available() {
        panic!(
            "expected evo to be installed for the cross-check, but {why}: run the README test command \
             (`bash scripts/test.sh`), which installs evo and puts it on PATH, or install it yourself with \
             `python3 -m pip install -r tests/evo/requirements.txt`"
        );
    }
    let dir = tempfile::tempdir().expect("a temporary directory");
    let cases = cases();
    let mut files: Vec<(PathBuf, PathBuf)> = Vec::new();
    for case in &cases {
        let (r, e) = (
            dir.path().join(format!("{}-ref.tum", case.name)),
            dir.path().join(format!("{}-est.tum", case.name)),
        );
        write_tum(&r, &case.reference).expect("reference written");
        write_tum(&e, &case.estimate).expect("estimate written");
        files.push((r, e));
    }
    let settings = settings();
    let jobs: Vec<(usize, usize)> = (0..cases.len())
        .flat_map(|c| (0..settings.len()).map(move |s| (c, s)))
        .collect();
    let next = AtomicUsize::new(0);
    let problems = Mutex::new(Vec::new());
    let lines = Mutex::new(Vec::new());
    std::thread::scope(|scope| {
        for _ in 0..2 {
            scope.spawn(|| {
                while let Some(&(c, s)) = jobs.get(next.fetch_add(1, Ordering::Relaxed)) {
                    let (case, setting, (r, e)) = (&cases[c], &settings[s], &files[c]);
                    let label = format!("{} / {}", case.name, setting.name);
                    let reference = read_tum(r).expect("reference read back");
                    let estimate = read_tum(e).expect("estimate read back");
                    let association = Association {
                        offset: case.t_offset,
                        ..Default::default()
                    };
                    let with_offset = |pairing: Pairing| match pairing {
                        Pairing::ByStamp(a) => Pairing::ByStamp(Association {
                            offset: case.t_offset,
                            ..a
                        }),
                        Pairing::ByIndex => Pairing::ByStamp(association),
                    };
                    let (tool, ours) = match &setting.kind {
                        Kind::Ape(o) => {
                            let o = ApeOptions {
                                pairing: with_offset(o.pairing),
                                ..*o
                            };
                            (
                                "evo_ape",
                                evaluate_ape(&reference, &estimate, &o)
                                    .map(|r| (r.stats, r.errors)),
                            )
                        }
                        Kind::Rpe(o) => {
                            let o = RpeOptions {
                                pairing: with_offset(o.pairing),
                                ..*o
                            };
                            (
                                "evo_rpe",
                                evaluate_rpe(&reference, &estimate, &o)
                                    .map(|r| (r.stats, r.errors)),
                            )
                        }
                    };
                    let evo = run_evo(tool, r, e, case.t_offset, setting.evo_args);
                    let found = match (ours, evo) {
                        (Ok((stats, errors)), Ok(evo)) => {
                            lines.lock().expect("lock").push(format!(
                                "{label:<40} pairs {:>6} rmse ours {:.12e} evo {:.12e}",
                                stats.pairs, stats.rmse, evo.stats.rmse
                            ));
                            compare(&label, &stats, &errors, &evo)
                        }
                        (Err(ours), Ok(_)) => vec![format!(
                            "{label}: expected a result like evo, got error {ours}"
                        )],
                        (Ok(_), Err(evo)) => {
                            vec![format!("{label}: expected evo to run, it failed: {evo}")]
                        }
                        (Err(ours), Err(evo)) => {
                            vec![format!("{label}: both failed; ours: {ours}; evo: {evo}")]
                        }
                    };
                    problems.lock().expect("lock").extend(found);
                }
            });
        }
    });
    let mut lines = lines.into_inner().expect("lock");
    lines.sort();
    println!("{}", lines.join("\n"));
    let problems = problems.into_inner().expect("lock");
    assert!(
        problems.is_empty(),
        "expected every pair count, statistic and error equal to evo's within {RELATIVE_TOLERANCE} relative:\n{}",
        problems.join("\n")
    );
    assert_eq!(
        lines.len(),
        jobs.len(),
        "expected every case and setting compared"
    );
}
