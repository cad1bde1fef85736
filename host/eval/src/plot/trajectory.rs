//! Top view (x right, y up) of a reference (dark grey, drawn on top) and an aligned
//! estimate coloured by its error with viridis (red where an error is missing), as evo's `--plot_mode xy`
//! with colour-mapped APE.

use std::path::Path;

use nalgebra::Isometry3;

use super::{Bounds, Canvas, Drawing, Rgb, Svg, viridis};
use crate::EvalError;

const WIDTH: u32 = 1200;
const HEIGHT: u32 = 900;
const REFERENCE: Rgb = [90, 90, 90];
const MISSING: Rgb = [200, 80, 80];
/// Colour levels; consecutive segments with the same level become one polyline.
const LEVELS: f64 = 64.0;

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
    let data = Bounds::around(reference.iter().chain(&estimate).copied(), 0.0)
        .ok_or_else(|| EvalError::InvalidOption("nothing to plot".into()))?;
    let margin = 0.05 * data.width().max(data.height()).max(1e-3);
    // Room on the right for the colour bar.
    let bounds = Bounds::new(
        (data.min.0 - margin, data.min.1 - margin),
        (
            data.max.0 + margin + 0.15 * data.width().max(data.height()),
            data.max.1 + margin,
        ),
    );
    let (lo, hi) = errors
        .iter()
        .filter(|e| e.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &e| {
            (lo.min(e), hi.max(e))
        });
    let extension = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match extension.as_deref() {
        Some("png") => {
            let mut canvas = Canvas::new(WIDTH, HEIGHT, bounds);
            draw(&mut canvas, &reference, &estimate, errors, (lo, hi));
            canvas.save_png(path)
        }
        Some("svg") => {
            let mut svg = Svg::new(WIDTH, HEIGHT, bounds);
            let (bar_min, bar_max) = draw(&mut svg, &reference, &estimate, errors, (lo, hi));
            let m = *svg.mapping();
            let label = |px: (f64, f64)| m.to_world(px);
            let (bx, _) = m.to_pixel(bar_max);
            let (_, top) = m.to_pixel(bar_max);
            let (_, bottom) = m.to_pixel(bar_min);
            svg.text(
                label((bx + 6.0, top + 6.0)),
                14.0,
                [0, 0, 0],
                &format!("{hi:.4}"),
            );
            svg.text(
                label((bx + 6.0, bottom)),
                14.0,
                [0, 0, 0],
                &format!("{lo:.4}"),
            );
            svg.save(path)
        }
        _ => Err(EvalError::Encode {
            path: path.to_path_buf(),
            message: "unknown image type: use a .png or .svg extension".into(),
        }),
    }
}

/// Draws the paths and the colour bar; returns the bar's world corners (min, max).
fn draw<D: Drawing>(
    d: &mut D,
    reference: &[(f64, f64)],
    estimate: &[(f64, f64)],
    errors: &[f64],
    (lo, hi): (f64, f64),
) -> ((f64, f64), (f64, f64)) {
    let level = |e: f64| -> Option<u32> {
        e.is_finite().then(|| {
            let t = if hi > lo { (e - lo) / (hi - lo) } else { 0.0 };
            (t * (LEVELS - 1.0)).round() as u32
        })
    };
    let color = |l: Option<u32>| l.map_or(MISSING, |l| viridis(f64::from(l) / (LEVELS - 1.0)));
    let mut start = 0;
    for i in 1..=estimate.len() {
        let boundary = i == estimate.len() || level(errors[i]) != level(errors[start]);
        if boundary {
            // Run start..i shares a colour; include the next point to stay connected.
            let end = (i + 1).min(estimate.len());
            d.polyline(&estimate[start..end], color(level(errors[start])), 3.0);
            start = i;
        }
    }
    // The reference on top, thin, so it stays visible under a noisy estimate.
    d.polyline(reference, REFERENCE, 1.5);
    if let Some(&first) = estimate.first() {
        d.circle(first, 5.0, [0, 0, 0]);
    }
    let m = *d.bounds_mapping();
    let (x0, x1) = (f64::from(m.width()) - 70.0, f64::from(m.width()) - 50.0);
    let (top, bottom) = (60.0, f64::from(m.height()) - 60.0);
    let steps = 64;
    for k in 0..steps {
        let y_hi = bottom - (bottom - top) * f64::from(k + 1) / f64::from(steps);
        let y_lo = bottom - (bottom - top) * f64::from(k) / f64::from(steps);
        d.fill_rect(
            m.to_world((x0, y_lo)),
            m.to_world((x1, y_hi)),
            viridis(f64::from(k) / f64::from(steps - 1)),
        );
    }
    (m.to_world((x0, bottom)), m.to_world((x1, top)))
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
        assert!(
            text.contains("<polyline") && text.contains("0.4900"),
            "expected paths and the max label in the SVG"
        );
        let err = plot_trajectories(dir.path().join("p.jpg"), &poses, &poses, &errors).unwrap_err();
        assert!(
            err.to_string().contains("p.jpg"),
            "expected the file named in {err}"
        );
    }
}
