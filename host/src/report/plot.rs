//! One top view per scenario, as PNG and SVG: a light metric grid, the ground truth in
//! black (drawn wider, so it shows as an outline where an estimate lies on it) and every
//! ok system's aligned estimate in the system's colour, with a legend band below the
//! plot. The PNG has no font, so its legend is colour swatches only, in the same order
//! as the SVG legend, which also names them.

use std::path::{Path, PathBuf};

use anyhow::Context as _;
use eval::plot::{Bounds, Canvas, Drawing, Mapping, Rgb, Svg};

use super::table::Table;
use super::{RunStatus, ScenarioTruth};

const WIDTH_PX: u32 = 1000;
/// Limits of the plot area's height (the legend band comes below it).
const MIN_PLOT_HEIGHT_PX: f64 = 300.0;
const MAX_PLOT_HEIGHT_PX: f64 = 1000.0;
const LEGEND_ROW_PX: f64 = 22.0;
const LEGEND_PAD_PX: f64 = 12.0;
/// Grid lines at least this far apart.
const MIN_GRID_PX: f64 = 40.0;

const GROUND_TRUTH: Rgb = [0, 0, 0];
const GRID: Rgb = [225, 225, 225];
const FAILED: Rgb = [150, 150, 150];
const WHITE: Rgb = [255, 255, 255];
/// Okabe & Ito's colour-blind-safe palette (without black, which is the ground truth),
/// yellow last as it is faint on white; plugin `i` gets colour `i % 7`.
const PALETTE: [Rgb; 7] = [
    [0, 114, 178],   // blue
    [213, 94, 0],    // vermillion
    [0, 158, 115],   // bluish green
    [204, 121, 167], // reddish purple
    [86, 180, 233],  // sky blue
    [230, 159, 0],   // orange
    [240, 228, 66],  // yellow
];

/// The colour of the plugin at `index` in the plugin order.
pub(super) fn plugin_color(index: usize) -> Rgb {
    PALETTE[index % PALETTE.len()]
}

/// What one legend row shows.
enum Swatch {
    Line(Rgb),
    /// A hollow box: a system that failed on this scenario.
    Failed,
}

/// Everything drawn for one scenario.
struct Scene<'a> {
    truth: &'a [(f64, f64)],
    /// Estimates of ok systems with their colours, in plugin order.
    estimates: Vec<(&'a [(f64, f64)], Rgb)>,
    /// Legend rows: swatch and SVG label.
    legend: Vec<(Swatch, String)>,
}

/// Writes `<scenario>.png` and `.svg` into `dir` for every scenario of `table`.
pub(super) fn write_plots(
    dir: &Path,
    table: &Table,
    truths: &[ScenarioTruth],
) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let mut stems: Vec<String> = Vec::new();
    for &scenario in &table.scenarios {
        let stem = file_stem(scenario);
        anyhow::ensure!(
            !stems.contains(&stem),
            "scenario {scenario:?} would overwrite the plot of another scenario ({stem}.png): expected names that differ in letters, digits, '.', '-' or '_'"
        );
        let scene = scene(table, scenario, truths);
        let (width, height, bounds, plot_height) = layout(&scene);

        let png = dir.join(format!("{stem}.png"));
        let mut canvas = Canvas::new(width, height, bounds);
        draw(&mut canvas, &scene, plot_height);
        canvas
            .save_png(&png)
            .with_context(|| format!("writing {}", png.display()))?;

        let svg_path: PathBuf = dir.join(format!("{stem}.svg"));
        let mut svg = Svg::new(width, height, bounds);
        let grid_step = draw(&mut svg, &scene, plot_height);
        let mapping = *svg.mapping();
        let labels = std::iter::once(format!("{scenario}: ground truth (grid {grid_step} m)"))
            .chain(scene.legend.iter().skip(1).map(|(_, label)| label.clone()));
        for (row, label) in labels.enumerate() {
            let (_, y) = legend_row_px(plot_height, row);
            svg.text(
                mapping.to_world((54.0, y + 5.0)),
                14.0,
                GROUND_TRUTH,
                &label,
            );
        }
        svg.save(&svg_path)
            .with_context(|| format!("writing {}", svg_path.display()))?;
        stems.push(stem);
    }
    Ok(())
}

/// The scenario name as a file stem: ASCII letters, digits, `.`, `-`, `_` kept, any
/// other character `_`, and never empty, `.` or `..`.
fn file_stem(scenario: &str) -> String {
    let stem: String = scenario
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || matches!(c, '.' | '-' | '_') {
                c
            } else {
                '_'
            }
        })
        .collect();
    if stem.is_empty() || stem.chars().all(|c| c == '.') {
        stem.replace('.', "_") + "_"
    } else {
        stem
    }
}

fn scene<'a>(table: &'a Table, scenario: &str, truths: &'a [ScenarioTruth]) -> Scene<'a> {
    let truth = truths
        .iter()
        .find(|t| t.scenario == scenario)
        .map_or(&[][..], |t| t.groundtruth_xy.as_slice());
    let mut scene = Scene {
        truth,
        estimates: Vec::new(),
        legend: vec![(Swatch::Line(GROUND_TRUTH), String::new())],
    };
    for column in table.columns_of(scenario) {
        let plugin = &column.run.plugin;
        match &column.run.status {
            RunStatus::Ok => {
                let color = plugin_color(column.plugin_index);
                scene.estimates.push((&column.run.estimate_xy, color));
                scene.legend.push((Swatch::Line(color), plugin.clone()));
            }
            RunStatus::Failed(_) => {
                let reason = column.failure.as_deref().unwrap_or_default();
                scene
                    .legend
                    .push((Swatch::Failed, format!("{plugin}: failed ({reason})")));
            }
        }
    }
    scene
}

/// Picture width and height, world bounds of the whole picture and the plot area's
/// height in pixels (the legend band is below it). The data are centred in the plot
/// area, 1000 px wide unless that would make the plot area taller than its maximum.
fn layout(scene: &Scene) -> (u32, u32, Bounds, f64) {
    let points = scene
        .estimates
        .iter()
        .flat_map(|(xy, _)| xy.iter())
        .chain(scene.truth)
        .copied();
    let data = Bounds::around(points, 0.0).unwrap_or(Bounds::new((-1.0, -1.0), (1.0, 1.0)));
    let margin = (0.05 * data.width().max(data.height())).max(0.5);
    let (data_w, data_h) = (data.width() + 2.0 * margin, data.height() + 2.0 * margin);
    let width = f64::from(WIDTH_PX);
    let px_per_m = (width / data_w).min(MAX_PLOT_HEIGHT_PX / data_h);
    let plot_height = (data_h * px_per_m).max(MIN_PLOT_HEIGHT_PX).ceil();
    let legend_height = 2.0 * LEGEND_PAD_PX + LEGEND_ROW_PX * scene.legend.len() as f64;
    let height = plot_height + legend_height;
    let center = (
        (data.min.0 + data.max.0) / 2.0,
        (data.min.1 + data.max.1) / 2.0,
    );
    let top = center.1 + plot_height / px_per_m / 2.0;
    let half_width = width / px_per_m / 2.0;
    let bounds = Bounds::new(
        (center.0 - half_width, top - height / px_per_m),
        (center.0 + half_width, top),
    );
    (WIDTH_PX, height as u32, bounds, plot_height)
}

/// Pixel position (left, vertical centre) of legend row `row`.
fn legend_row_px(plot_height: f64, row: usize) -> (f64, f64) {
    (
        16.0,
        plot_height + LEGEND_PAD_PX + LEGEND_ROW_PX * (row as f64 + 0.5),
    )
}

/// The smallest of 1, 2, 5 × 10^k metres at least [`MIN_GRID_PX`] apart.
fn grid_step(px_per_m: f64) -> f64 {
    let mut decade = 10f64.powi((MIN_GRID_PX / px_per_m).log10().floor() as i32);
    loop {
        for factor in [1.0, 2.0, 5.0] {
            if factor * decade * px_per_m >= MIN_GRID_PX {
                return factor * decade;
            }
        }
        decade *= 10.0;
    }
}

/// Draws the grid, trajectories and legend swatches; returns the grid step in metres.
fn draw<D: Drawing>(d: &mut D, scene: &Scene, plot_height: f64) -> f64 {
    let mapping: Mapping = *d.bounds_mapping();
    let world = |px: (f64, f64)| mapping.to_world(px);
    let (top_left, bottom_right) = (
        world((0.0, 0.0)),
        world((f64::from(mapping.width()), plot_height)),
    );

    let step = grid_step(mapping.px_per_unit());
    let first = |lo: f64| (lo / step).ceil() as i64;
    for i in first(top_left.0)..=(bottom_right.0 / step).floor() as i64 {
        let x = i as f64 * step;
        d.polyline(&[(x, bottom_right.1), (x, top_left.1)], GRID, 1.0);
    }
    for j in first(bottom_right.1)..=(top_left.1 / step).floor() as i64 {
        let y = j as f64 * step;
        d.polyline(&[(top_left.0, y), (bottom_right.0, y)], GRID, 1.0);
    }
    d.polyline(
        &[
            (top_left.0, bottom_right.1),
            (bottom_right.0, bottom_right.1),
        ],
        FAILED,
        1.0,
    );

    for part in finite_parts(scene.truth) {
        d.polyline(part, GROUND_TRUTH, 4.0);
    }
    for &(xy, color) in &scene.estimates {
        for part in finite_parts(xy) {
            d.polyline(part, color, 2.0);
        }
    }

    for (row, (swatch, _)) in scene.legend.iter().enumerate() {
        let (x, y) = legend_row_px(plot_height, row);
        let rect = |d: &mut D, (x0, y0): (f64, f64), (x1, y1): (f64, f64), color| {
            d.fill_rect(world((x0, y1)), world((x1, y0)), color);
        };
        match swatch {
            Swatch::Line(color) => rect(d, (x, y - 3.0), (x + 28.0, y + 3.0), *color),
            Swatch::Failed => {
                rect(d, (x, y - 6.0), (x + 28.0, y + 6.0), FAILED);
                rect(d, (x + 2.0, y - 4.0), (x + 26.0, y + 4.0), WHITE);
            }
        }
    }
    step
}

/// The runs of finite points of `xy` (a NaN or infinity breaks the line).
fn finite_parts(xy: &[(f64, f64)]) -> impl Iterator<Item = &[(f64, f64)]> {
    xy.split(|p| !(p.0.is_finite() && p.1.is_finite()))
        .filter(|part| !part.is_empty())
}
