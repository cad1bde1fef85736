//! Scores a finished run: APE (translation) of the final and of the online trajectory
//! against ground truth, as evo computes it.

use std::path::Path;

use anyhow::Context as _;
use eval::{Alignment, ApeOptions, Statistics};
use serde::Serialize;

use super::job::files;

/// metrics.json.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Metrics {
    pub alignment: String,
    /// APE translation of the final trajectory, metres.
    pub ape: Statistics,
    /// APE translation of the poses returned during the run, if any.
    pub online_ape: Option<Statistics>,
}

/// The scores and the aligned final estimate's top view.
#[derive(Debug, Clone)]
pub struct Scored {
    pub metrics: Metrics,
    pub estimate_xy: Vec<(f64, f64)>,
}

pub fn alignment_name(a: Alignment) -> &'static str {
    match a {
        Alignment::None => "none",
        Alignment::Origin => "origin",
        Alignment::Se3 => "se3",
        Alignment::Sim3 => "sim3",
        Alignment::Scale => "scale",
        Alignment::FourDof => "4dof",
    }
}

/// Evaluates the run in `dir` and writes its metrics.json.
pub fn evaluate(dir: &Path, alignment: Alignment) -> anyhow::Result<Scored> {
    let gt = eval::read_tum(dir.join(files::GROUNDTRUTH))?;
    let options = ApeOptions {
        alignment,
        ..ApeOptions::default()
    };
    let final_ = eval::evaluate_ape(&gt, &eval::read_tum(dir.join(files::ESTIMATE))?, &options)
        .with_context(|| format!("evaluating {}", dir.join(files::ESTIMATE).display()))?;
    let online_path = dir.join(files::ONLINE);
    let online_ape = if online_path.exists() {
        Some(eval::evaluate_ape(&gt, &eval::read_tum(&online_path)?, &options)?.stats)
    } else {
        None
    };
    let metrics = Metrics {
        alignment: alignment_name(alignment).to_owned(),
        ape: final_.stats,
        online_ape,
    };
    super::worker::write_json(&dir.join(files::METRICS), &metrics)?;
    let estimate_xy = final_
        .pairs
        .estimate
        .iter()
        .map(|p| (p.translation.x, p.translation.y))
        .collect();
    Ok(Scored {
        metrics,
        estimate_xy,
    })
}
