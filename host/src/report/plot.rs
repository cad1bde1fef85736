//! Top views of the trajectories per scenario (the paper's Fig. 3), as PNG and SVG from
//! one [`Chart`]: axes in metres, grid, title, and a legend below the plot that names
//! ground truth and every system (a failed one with its reason).

use std::path::{Path, PathBuf};

use anyhow::Context as _;
use eval::plot::{Chart, Mark, Rgb, Swatch};

use super::table::Table;
use super::{RunStatus, ScenarioTruth};

pub(super) const WIDTH_PX: u32 = 1000;

const GROUND_TRUTH: Rgb = [0, 0, 0];
/// Loop closures: grey when true (thin, under the estimates' colours, none of which is
/// grey), red and wider when false, so a false loop stands out.
pub(super) const TRUE_LOOP: Rgb = [110, 110, 110];
pub(super) const FALSE_LOOP: Rgb = [230, 0, 30];
/// Wrong joins of the final map: orange, between the two true places they join.
pub(super) const WRONG_JOIN: Rgb = [245, 130, 0];
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

/// A loop closure drawn on a top view: the segment between the two positions it joins
/// and whether ground truth judged it true.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoopSegment {
    pub from: (f64, f64),
    pub to: (f64, f64),
    pub true_loop: bool,
    /// A wrong join of the final map (`joins.json`), drawn between the two places it joins
    /// in ground truth, not an accepted loop.
    pub wrong_join: bool,
}

/// An ok run's aligned estimate (top view) and its loops.
pub type Drawn<'a> = (&'a [(f64, f64)], &'a [LoopSegment]);

/// One system's line on a scenario's top view.
#[derive(Debug, Clone)]
pub struct Track<'a> {
    pub plugin: &'a str,
    /// Position of the plugin in the bench's plugin order: its colour.
    pub plugin_index: usize,
    /// The aligned estimate and its loops; `Err(reason)` for a failed run.
    pub outcome: Result<Drawn<'a>, &'a str>,
}

/// The paper's Fig. 3 for one scenario: ground truth in black (wide, so it shows as an
/// outline where an estimate lies on it), every ok system's aligned estimate in its
/// colour, accepted loops as segments (true thin grey, false wider red) and the final map's
/// wrong joins between the two true places they join (orange), in metres with
/// equal scales; the legend names ground truth, every system (failed ones with their
/// reason) and the loop colours when there are loops.
pub fn scenario_chart(scenario: &str, truth: &[(f64, f64)], tracks: &[Track]) -> Chart {
    let mut chart = Chart::top_view(format!("{scenario}: aligned estimates over ground truth"));
    for part in finite_parts(truth) {
        chart.marks.push(Mark::Line {
            points: part.to_vec(),
            color: GROUND_TRUTH,
            width_px: 4,
        });
    }
    chart.legend.push((
        Swatch::Line {
            color: GROUND_TRUTH,
            width_px: 4,
        },
        "ground truth".into(),
    ));
    let (mut true_loops, mut false_loops, mut wrong_joins) = (Vec::new(), Vec::new(), Vec::new());
    for track in tracks {
        match track.outcome {
            Ok((xy, loops)) => {
                let color = plugin_color(track.plugin_index);
                for part in finite_parts(xy) {
                    chart.marks.push(Mark::Line {
                        points: part.to_vec(),
                        color,
                        width_px: 2,
                    });
                }
                chart
                    .legend
                    .push((Swatch::Line { color, width_px: 3 }, track.plugin.to_owned()));
                for l in loops {
                    let list = if l.wrong_join {
                        &mut wrong_joins
                    } else if l.true_loop {
                        &mut true_loops
                    } else {
                        &mut false_loops
                    };
                    list.push([l.from, l.to]);
                }
            }
            Err(reason) => chart.legend.push((
                Swatch::Hollow,
                format!("{}: failed ({reason})", track.plugin),
            )),
        }
    }
    for (segments, color, label) in [
        (true_loops, TRUE_LOOP, "true loop closures"),
        (false_loops, FALSE_LOOP, "false loop closures"),
        (
            wrong_joins,
            WRONG_JOIN,
            "wrong joins of the final map (between the true places)",
        ),
    ] {
        push_segments(&mut chart, segments, color, 1, label);
    }
    chart
}

/// Draws `segments` in `color`, `width_px` wide, with a legend entry "label (count)"; nothing
/// when there are none.
pub(super) fn push_segments(
    chart: &mut Chart,
    segments: Vec<[(f64, f64); 2]>,
    color: Rgb,
    width_px: u32,
    label: &str,
) {
    if segments.is_empty() {
        return;
    }
    chart.legend.push((
        Swatch::Line { color, width_px: 2 },
        format!("{label} ({})", segments.len()),
    ));
    chart.marks.push(Mark::Segments {
        segments,
        color,
        width_px,
    });
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
        let truth = truths
            .iter()
            .find(|t| t.scenario == scenario)
            .map_or(&[][..], |t| t.groundtruth_xy.as_slice());
        let tracks: Vec<Track> = table
            .columns_of(scenario)
            .map(|column| Track {
                plugin: &column.run.plugin,
                plugin_index: column.plugin_index,
                outcome: match &column.run.status {
                    RunStatus::Ok => Ok((column.run.estimate_xy.as_slice(), &[][..])),
                    RunStatus::Failed(_) => Err(column.failure.as_deref().unwrap_or_default()),
                },
            })
            .collect();
        let mut chart = scenario_chart(scenario, truth, &tracks);
        if chart.marks.is_empty() {
            // Nothing ran: an empty frame around the origin, so the legend still says why.
            chart.x_range = Some((-1.0, 1.0));
            chart.y_range = Some((-1.0, 1.0));
        }
        for (ext, bytes) in [
            ("png", chart.to_png(WIDTH_PX)?),
            ("svg", chart.to_svg(WIDTH_PX)?.into_bytes()),
        ] {
            let path: PathBuf = dir.join(format!("{stem}.{ext}"));
            std::fs::write(&path, bytes).with_context(|| format!("writing {}", path.display()))?;
        }
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

/// The runs of finite points of `xy` (a NaN or infinity breaks the line).
fn finite_parts(xy: &[(f64, f64)]) -> impl Iterator<Item = &[(f64, f64)]> {
    xy.split(|p| !(p.0.is_finite() && p.1.is_finite()))
        .filter(|part| !part.is_empty())
}
