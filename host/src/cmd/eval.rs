//! `vinebench eval GT EST`: APE or RPE of an estimated trajectory against ground truth,
//! with evo's semantics and table (see the `eval` crate), optionally as one JSON line,
//! a KITTI-style drift table and a top-view plot.

use std::path::PathBuf;

use anyhow::bail;
use clap::ValueEnum;
use eval::{
    Alignment, ApeOptions, Association, DeltaUnit, DriftOptions, Format, Pairing, PoseRelation,
    RpeOptions, Sim3, Statistics, drift, evaluate_ape, evaluate_rpe, plot::plot_trajectories,
    read_trajectory,
};

/// Arguments of `vinebench eval`.
#[derive(Debug, clap::Args)]
pub struct EvalArgs {
    /// Ground-truth (reference) trajectory file.
    pub gt: PathBuf,
    /// Estimated trajectory file.
    pub est: PathBuf,
    /// File format of both trajectories.
    #[arg(long, value_enum, default_value_t = FormatArg::Tum)]
    pub format: FormatArg,
    /// KITTI times file of the ground truth (stamps in seconds, one per line); without
    /// times files KITTI poses are paired by index.
    #[arg(long, requires = "est_times")]
    pub gt_times: Option<PathBuf>,
    /// KITTI times file of the estimate.
    #[arg(long, requires = "gt_times")]
    pub est_times: Option<PathBuf>,
    /// Alignment of the estimate to the ground truth.
    #[arg(long, value_enum, default_value_t = AlignArg::None)]
    pub align: AlignArg,
    /// Align on the first N pose pairs only.
    #[arg(long, value_name = "N")]
    pub n_to_align: Option<usize>,
    /// Pose relation of the error (evo's names).
    #[arg(long, short = 'r', value_enum, default_value_t = RelationArg::TransPart)]
    pub relation: RelationArg,
    /// Compute the RPE over steps of this size instead of the APE.
    #[arg(long, value_name = "DELTA")]
    pub rpe_delta: Option<f64>,
    /// Unit of the RPE step: m (metres of path) or f (frames).
    #[arg(long, value_enum, default_value_t = UnitArg::F)]
    pub rpe_unit: UnitArg,
    /// RPE over all pairs one step apart, not only consecutive steps.
    #[arg(long)]
    pub rpe_all_pairs: bool,
    /// Largest time difference of associated poses, seconds.
    #[arg(long, default_value_t = 0.01, value_name = "SECONDS")]
    pub t_max_diff: f64,
    /// Time offset added to the estimate's stamps, seconds.
    #[arg(
        long,
        default_value_t = 0.0,
        allow_hyphen_values = true,
        value_name = "SECONDS"
    )]
    pub t_offset: f64,
    /// Interpolate the denser trajectory at the matched stamps (linear position, slerp
    /// rotation) instead of snapping to its closest pose.
    #[arg(long)]
    pub interpolate: bool,
    /// Also print KITTI-style drift over these segment lengths in metres (e.g. 5,10,20).
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "METRES",
        conflicts_with = "json"
    )]
    pub drift: Option<Vec<f64>>,
    /// Print only `{"pairs": n, "rmse": …, "mean": …, "median": …, "std": …, "min": …,
    /// "max": …, "sse": …}`.
    #[arg(long)]
    pub json: bool,
    /// Write a top view of the ground truth and the aligned estimate coloured by error
    /// (PNG or SVG, by extension).
    #[arg(long, value_name = "FILE")]
    pub plot: Option<PathBuf>,
}

/// Trajectory file formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum FormatArg {
    /// `t x y z qx qy qz qw`.
    Tum,
    /// 3x4 matrices row-major, optional times files.
    Kitti,
}

/// Alignments.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum AlignArg {
    /// No alignment.
    None,
    /// First poses made equal.
    Origin,
    /// SE(3) Umeyama.
    Se3,
    /// Sim(3) Umeyama (with scale).
    Sim3,
    /// Scale only.
    Scale,
    /// Yaw and translation.
    #[value(name = "4dof")]
    FourDof,
}

/// Pose relations, named as in evo's `-r`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum RelationArg {
    /// Translation, metres.
    #[value(name = "trans_part", alias = "trans")]
    TransPart,
    /// Rotation angle, degrees.
    #[value(name = "angle_deg")]
    AngleDeg,
    /// Rotation angle, radians.
    #[value(name = "angle_rad")]
    AngleRad,
    /// ‖R - I‖, unitless.
    #[value(name = "rot_part")]
    RotPart,
    /// ‖E - I‖, unitless.
    Full,
}

/// RPE step units.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum UnitArg {
    /// Metres of travelled path.
    M,
    /// Frames (poses).
    F,
}

/// Runs `vinebench eval`.
pub fn run(args: &EvalArgs) -> anyhow::Result<()> {
    let (format, pairing) = match args.format {
        FormatArg::Tum => (Format::Tum, Pairing::ByStamp(association(args))),
        FormatArg::Kitti if args.gt_times.is_some() => {
            (Format::Kitti, Pairing::ByStamp(association(args)))
        }
        FormatArg::Kitti => (Format::Kitti, Pairing::ByIndex),
    };
    if format == Format::Tum && (args.gt_times.is_some() || args.est_times.is_some()) {
        bail!("--gt-times/--est-times are only for --format kitti");
    }
    // The two files are independent: parse them on two threads.
    let (reference, estimate) = std::thread::scope(|scope| {
        let reference = scope.spawn(|| read_trajectory(&args.gt, format, args.gt_times.as_deref()));
        let estimate = read_trajectory(&args.est, format, args.est_times.as_deref());
        (reference.join().expect("reading does not panic"), estimate)
    });
    let (reference, estimate) = (reference?, estimate?);
    let alignment = match args.align {
        AlignArg::None => Alignment::None,
        AlignArg::Origin => Alignment::Origin,
        AlignArg::Se3 => Alignment::Se3,
        AlignArg::Sim3 => Alignment::Sim3,
        AlignArg::Scale => Alignment::Scale,
        AlignArg::FourDof => Alignment::FourDof,
    };
    let relation = match args.relation {
        RelationArg::TransPart => PoseRelation::Translation,
        RelationArg::AngleDeg => PoseRelation::AngleDeg,
        RelationArg::AngleRad => PoseRelation::AngleRad,
        RelationArg::RotPart => PoseRelation::RotationPart,
        RelationArg::Full => PoseRelation::Full,
    };

    let (title, stats, pairs, transform, pose_errors) = match args.rpe_delta {
        None => {
            let options = ApeOptions {
                pairing,
                alignment,
                n_to_align: args.n_to_align,
                relation,
            };
            let result = evaluate_ape(&reference, &estimate, &options)?;
            let title = format!("APE w.r.t. {} ({})", relation.describe(), relation.unit());
            (
                title,
                result.stats,
                result.pairs,
                result.transform,
                result.errors,
            )
        }
        Some(delta) => {
            let unit = match args.rpe_unit {
                UnitArg::M => DeltaUnit::Metres,
                UnitArg::F => DeltaUnit::Frames,
            };
            let options = RpeOptions {
                pairing,
                alignment,
                n_to_align: args.n_to_align,
                relation,
                delta,
                unit,
                all_pairs: args.rpe_all_pairs,
                ..Default::default()
            };
            let result = evaluate_rpe(&reference, &estimate, &options)?;
            let title = format!(
                "RPE w.r.t. {} ({})\nfor delta = {delta} ({}) using {} pairs",
                relation.describe(),
                relation.unit(),
                match unit {
                    DeltaUnit::Metres => "m",
                    DeltaUnit::Frames => "frames",
                },
                if args.rpe_all_pairs {
                    "all"
                } else {
                    "consecutive"
                }
            );
            // One error per pose for the plot: at the end pose of each pair.
            let mut per_pose = vec![f64::NAN; result.pairs.len()];
            for (&(_, j), &e) in result.id_pairs.iter().zip(&result.errors) {
                per_pose[j] = e;
            }
            (
                title,
                result.stats,
                result.pairs,
                result.transform,
                per_pose,
            )
        }
    };

    let drifts = match &args.drift {
        Some(lengths) => {
            let options = DriftOptions {
                lengths: lengths.clone(),
                ..Default::default()
            };
            Some((
                options.step,
                drift(&pairs.reference, &pairs.estimate, &options)?,
            ))
        }
        None => None,
    };
    if let Some(path) = &args.plot {
        plot_trajectories(path, &pairs.reference, &pairs.estimate, &pose_errors)?;
    }
    if args.json {
        crate::out!("{}", json_line(&stats)?);
        return Ok(());
    }
    crate::out!(
        "{title}\n{}\n",
        alignment_note(alignment, args.n_to_align, &transform)
    );
    crate::out!("{}", table(&stats));
    if let Some((step, drifts)) = drifts {
        crate::out!("\nKITTI-style drift (segments every {step} poses)");
        crate::out!(
            "{:>10}  {:>8}  {:>14}  {:>18}",
            "length m",
            "segments",
            "translation %",
            "rotation deg/100m"
        );
        for d in drifts {
            let length = if d.length > 0.0 {
                format!("{}", d.length)
            } else {
                "all".to_owned()
            };
            crate::out!(
                "{length:>10}  {:>8}  {:>14.6}  {:>18.6}",
                d.segments,
                d.translation_percent,
                d.rotation_deg_per_100m
            );
        }
    }
    Ok(())
}

fn association(args: &EvalArgs) -> Association {
    Association {
        max_diff: args.t_max_diff,
        offset: args.t_offset,
        interpolate: args.interpolate,
    }
}

/// evo's wording of the alignment under the title.
fn alignment_note(alignment: Alignment, n_to_align: Option<usize>, transform: &Sim3) -> String {
    let note = match alignment {
        Alignment::None => "(not aligned)".to_owned(),
        Alignment::Origin => "(with origin alignment)".to_owned(),
        Alignment::Se3 => "(with SE(3) Umeyama alignment)".to_owned(),
        Alignment::Sim3 => format!(
            "(with Sim(3) Umeyama alignment, scale {:.6})",
            transform.scale
        ),
        Alignment::Scale => format!("(scale corrected, scale {:.6})", transform.scale),
        Alignment::FourDof => "(with 4-DoF yaw + translation alignment)".to_owned(),
    };
    match n_to_align {
        Some(n) if !matches!(alignment, Alignment::None | Alignment::Origin) => {
            format!("{note} (aligned poses: {n})")
        }
        _ => note,
    }
}

/// The statistics as evo prints them: names right-aligned, alphabetical, 6 decimals.
fn table(s: &Statistics) -> String {
    let rows = [
        ("max", s.max),
        ("mean", s.mean),
        ("median", s.median),
        ("min", s.min),
        ("rmse", s.rmse),
        ("sse", s.sse),
        ("std", s.std),
    ];
    let mut out = format!("{:>10}\t{}", "pairs", s.pairs);
    for (name, value) in rows {
        out.push_str(&format!("\n{name:>10}\t{value:.6}"));
    }
    out
}

/// `{"pairs": n, "rmse": …, "mean": …, "median": …, "std": …, "min": …, "max": …, "sse": …}`.
fn json_line(s: &Statistics) -> anyhow::Result<String> {
    let number = |v: f64| serde_json::to_string(&v);
    Ok(format!(
        r#"{{"pairs": {}, "rmse": {}, "mean": {}, "median": {}, "std": {}, "min": {}, "max": {}, "sse": {}}}"#,
        s.pairs,
        number(s.rmse)?,
        number(s.mean)?,
        number(s.median)?,
        number(s.std)?,
        number(s.min)?,
        number(s.max)?,
        number(s.sse)?
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn json_line_has_the_documented_shape() {
        let s = Statistics {
            pairs: 3,
            rmse: 0.5,
            mean: 0.25,
            median: 0.2,
            std: 0.1,
            min: 0.0,
            max: 1.0,
            sse: 0.75,
        };
        assert_eq!(
            json_line(&s).unwrap(),
            r#"{"pairs": 3, "rmse": 0.5, "mean": 0.25, "median": 0.2, "std": 0.1, "min": 0.0, "max": 1.0, "sse": 0.75}"#,
            "expected the documented key order and spacing"
        );
    }
}
