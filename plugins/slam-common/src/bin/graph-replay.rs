//! `graph-replay FILE --backend NAME [--batch] [--json]`: replays a g2o/TORO/City10000
//! pose graph through one of the shared backends and prints what it reached: GTSAM's
//! graph error of the final estimate, time, the slowest update, and with `--groundtruth`
//! the ATE RMSE after alignment. The formats, the priors and the replay are documented in
//! `slam_common::factor_graph::posegraph`.
//!
//! A bare FILE name that does not exist is looked up in GTSAM's example data of the
//! workspace's venv (`target/gtsam-venv/lib/python*/site-packages/gtsam/Data/`).

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use clap::Parser;
use slam_common::factor_graph::backend::{BackendConfig, from_config};
use slam_common::factor_graph::posegraph::{self, Format};

#[derive(Debug, Parser)]
#[command(about = "Replay a pose-graph file through a vinebench backend")]
struct Args {
    /// g2o / TORO / City10000 file.
    file: PathBuf,
    /// Backend name: "factrs", "isam2" or "gtsam".
    #[arg(long)]
    backend: String,
    /// One full update over the whole graph instead of one incremental update per pose.
    #[arg(long)]
    batch: bool,
    /// One JSON line instead of a readable one.
    #[arg(long)]
    json: bool,
    /// File layout: auto, g2o (g2o and TORO) or city10000.
    #[arg(long, default_value = "auto")]
    format: String,
    /// Ground truth (a graph file, or lines of `x y θ`) for the ATE.
    #[arg(long)]
    groundtruth: Option<PathBuf>,
    /// Writes per-update times as CSV (index,key,factors,seconds).
    #[arg(long)]
    profile: Option<PathBuf>,
    /// Writes the final estimate as g2o `VERTEX_SE3:QUAT` lines.
    #[arg(long)]
    estimate: Option<PathBuf>,
    /// factrs: keyframes an incremental update may move.
    #[arg(long)]
    window: Option<usize>,
    /// factrs: LM iterations per update; iSAM2: updates of a full one.
    #[arg(long)]
    max_iterations: Option<usize>,
    /// iSAM2: relinearizeThreshold.
    #[arg(long)]
    relinearize_threshold: Option<f64>,
    /// iSAM2: relinearizeSkip.
    #[arg(long)]
    relinearize_skip: Option<usize>,
    /// iSAM2: wildfireThreshold.
    #[arg(long)]
    wildfire_threshold: Option<f64>,
}

/// `file` itself, or for a bare name that does not exist, GTSAM's example data file of
/// that name in the workspace's venv.
fn resolve(file: &Path) -> PathBuf {
    if file.exists() || file.components().count() != 1 {
        return file.to_path_buf();
    }
    let lib = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../target/gtsam-venv/lib");
    std::fs::read_dir(&lib)
        .into_iter()
        .flatten()
        .flatten()
        .map(|python| python.path().join("site-packages/gtsam/Data").join(file))
        .find(|p| p.exists())
        .unwrap_or_else(|| file.to_path_buf())
}

fn main() -> Result<()> {
    let args = Args::parse();
    let format = match args.format.as_str() {
        "auto" => Format::Auto,
        "g2o" | "toro" => Format::G2o,
        "city10000" => Format::City10000,
        other => anyhow::bail!("unknown --format {other:?} (auto, g2o, city10000)"),
    };
    // The knobs go through the `[backend]` table's deserialiser, as a plugin's
    // configuration would: a knob this build's `BackendConfig` lacks is a clear error.
    let mut table = serde_json::json!({ "name": args.backend });
    let knobs = [
        ("window", args.window.map(serde_json::Value::from)),
        ("max_iterations", args.max_iterations.map(Into::into)),
        (
            "relinearize_threshold",
            args.relinearize_threshold.map(Into::into),
        ),
        ("relinearize_skip", args.relinearize_skip.map(Into::into)),
        (
            "wildfire_threshold",
            args.wildfire_threshold.map(Into::into),
        ),
    ];
    for (key, value) in knobs {
        if let Some(v) = value {
            table[key] = v;
        }
    }
    let config: BackendConfig = serde_json::from_value(table).context("backend settings")?;

    let file = resolve(&args.file);
    let graph = posegraph::read(&file, format)?;
    let truth = args
        .groundtruth
        .as_deref()
        .map(|p| posegraph::read_trajectory(&resolve(p)))
        .transpose()?;
    let mut backend = from_config(&config)?;
    let report = posegraph::replay(&graph, backend.as_mut(), args.batch)?;
    let ate = truth
        .map(|(_, t)| posegraph::ate_rmse(&report.estimate, &t, graph.planar))
        .transpose()?;

    if let Some(path) = &args.profile {
        let mut out = std::io::BufWriter::new(
            std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?,
        );
        writeln!(out, "index,key,factors,seconds")?;
        for u in &report.updates {
            writeln!(out, "{},{},{},{:.9}", u.index, u.key, u.factors, u.seconds)?;
        }
        out.flush()?;
    }

    if let Some(path) = &args.estimate {
        let mut out = std::io::BufWriter::new(
            std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?,
        );
        for (k, p) in &report.estimate {
            let (t, q) = (p.translation.vector, p.rotation.coords);
            writeln!(
                out,
                "VERTEX_SE3:QUAT {k} {:.17e} {:.17e} {:.17e} {:.17e} {:.17e} {:.17e} {:.17e}",
                t.x, t.y, t.z, q.x, q.y, q.z, q.w
            )?;
        }
        out.flush()?;
    }

    let mode = if args.batch { "batch" } else { "incremental" };
    if args.json {
        let mut line = serde_json::json!({
            "backend": args.backend,
            "mode": mode,
            "file": file.display().to_string(),
            "poses": report.poses,
            "factors": report.factors,
            "initial_error": report.initial_error,
            "final_error": report.final_error,
            "seconds": report.seconds,
            "max_update_s": report.max_update_s,
        });
        if let Some((rmse, n)) = ate {
            line["ate_rmse_m"] = rmse.into();
            line["ate_poses"] = n.into();
        }
        println!("{line}");
    } else {
        let ate = ate.map_or(String::new(), |(rmse, n)| {
            format!(", ATE RMSE {rmse:.4} m over {n} poses")
        });
        println!(
            "{} {mode} {}: {} poses, {} factors, error {:.6} -> {:.6}, {:.3} s (slowest update {:.4} s){ate}",
            args.backend,
            file.display(),
            report.poses,
            report.factors,
            report.initial_error,
            report.final_error,
            report.seconds,
            report.max_update_s,
        );
    }
    Ok(())
}
