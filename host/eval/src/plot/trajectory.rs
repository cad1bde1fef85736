//! Top view (x right, y up) of a reference (dark grey, drawn on top) and an aligned
//! estimate coloured by its error with viridis (red where an error is missing), as evo's
//! `--plot_mode xy` with colour-mapped APE.

use std::path::Path;

use nalgebra::Isometry3;

use super::{Chart, ColorBar, Mark, Rgb, Swatch, viridis};
use crate::EvalError;

const WIDTH: u32 = 1200;
const REFERENCE: Rgb = [90, 90, 90];
const MISSING: Rgb = [200, 80, 80];

/// The segments of `points` coloured by `values` (one per point, the colour of a segment
/// is its first point's) with viridis over `(lo, hi)`; `MISSING` red where a value is not
/// finite.
pub fn error_colored_path(points: &[(f64, f64)], values: &[f64], (lo, hi): (f64, f64)) -> Mark {
    let color = |e: f64| {
        if e.is_finite() {
            viridis(if hi > lo { (e - lo) / (hi - lo) } else { 0.0 })
        } else {
            MISSING
        }
    };
    Mark::ColoredSegments {
        segments: points
            .windows(2)
            .zip(values)
            .map(|(w, &e)| ([w[0], w[1]], color(e)))
            .collect(),
        width_px: 3,
    }
}

/// Writes a top view of `reference` (grey) and `estimate` coloured by `errors` (one per
/// estimate pose, NaN for none) as PNG or SVG, chosen by the extension of `path`.
pub fn plot_trajectories(
    path: impl AsRef<Path>,
    reference: &[Isometry3<f64>],
    estimate: &[Isometry3<f64>],
    errors: &[f64],
) -> Result<(), EvalError> {
    let path = path.as_ref();
    assert_eq!(estimate.len(), errors.len(), "one error per estimate pose");
    let xy = |poses: &[Isometry3<f64>]| -> Vec<(f64, f64)> {
        poses
            .iter()
            .map(|p| (p.translation.x, p.translation.y))
            .collect()
    };
    let (reference, estimate) = (xy(reference), xy(estimate));
    let (lo, hi) = errors
        .iter()
        .filter(|e| e.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &e| {
            (lo.min(e), hi.max(e))
        });
    let mut chart = Chart::top_view("APE (translation) along the aligned estimate");
    chart
        .marks
        .push(error_colored_path(&estimate, errors, (lo, hi)));
    // The reference on top, thin, so it stays visible under a noisy estimate.
    chart.marks.push(Mark::Line {
        points: reference,
        color: REFERENCE,
        width_px: 1,
    });
    if let Some(&first) = estimate.first() {
        chart.marks.push(Mark::Dots {
            points: vec![first],
            color: [0, 0, 0],
            radius_px: 5,
        });
    }
    chart.legend.push((
        Swatch::Line {
            color: REFERENCE,
            width_px: 2,
        },
        "reference".into(),
    ));
    chart.legend.push((
        Swatch::Line {
            color: viridis(0.5),
            width_px: 3,
        },
        "estimate (colour: APE)".into(),
    ));
    if errors.iter().any(|e| !e.is_finite()) {
        chart.legend.push((
            Swatch::Line {
                color: MISSING,
                width_px: 3,
            },
            "estimate without a reference pose".into(),
        ));
    }
    if lo.is_finite() {
        chart.color_bar = Some(ColorBar {
            label: "APE translation (m)".into(),
            min: lo,
            max: hi,
        });
    }
    chart.save(path, WIDTH)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_png_and_svg_and_rejects_other_extensions() {
        let dir = tempfile::tempdir().unwrap();
        let poses: Vec<_> = (0..50)
            .map(|i| Isometry3::translation(i as f64 * 0.1, (i as f64 * 0.2).sin(), 0.0))
            .collect();
        let errors: Vec<f64> = (0..50)
            .map(|i| if i == 10 { f64::NAN } else { i as f64 * 0.01 })
            .collect();
        let png = dir.path().join("p.png");
        plot_trajectories(&png, &poses, &poses, &errors).unwrap();
        assert!(
            std::fs::metadata(&png).unwrap().len() > 1000,
            "expected a non-trivial PNG"
        );
        let svg = dir.path().join("p.svg");
        plot_trajectories(&svg, &poses, &poses, &errors).unwrap();
        let text = std::fs::read_to_string(&svg).unwrap();
        assert!(text.contains("<polyline"), "expected paths in the SVG");
        let texts = crate::plot::chart::tests::svg_texts(&text);
        for expected in ["0.49", "APE translation (m)", "reference", "x (m)"] {
            assert!(
                texts.contains(&expected),
                "expected {expected:?} in the SVG's texts {texts:?}"
            );
        }
        let err = plot_trajectories(dir.path().join("p.jpg"), &poses, &poses, &errors).unwrap_err();
        assert!(
            err.to_string().contains("p.jpg"),
            "expected the file named in {err}"
        );
    }
}
