//! A sweep's files from its aggregate ([`crate::results::aggregate`]), each a pure function
//! of it:
//! - `sweep.json` and `sweep.csv`: accuracy (ATE, loops, counts). They hold nothing measured
//!   with a clock, so an interrupted and resumed sweep, or one run on Slurm, gives them
//!   byte-identical to an uninterrupted local one.
//! - `speed.csv`: real-time factor, CPU time and peak memory, which depend on the machine.
//! - `sweep.md`: both, as tables, and the failed runs with their reasons.
//! - `plots/<scenario>-ate-vs-<axis>.svg` and `.png` (the same chart): ATE RMSE mean ± std
//!   (error bars over the seeds) against each axis that takes two values or more, one line
//!   per system and point of the other axes.
//! - `report.html` ([`super::html::sweep_page`]).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use anyhow::Context as _;
use eval::plot::{Chart, Height, Mark, Rgb, Swatch};

use crate::results::aggregate::{Aggregate, Row, Speed, Summary};
use crate::results::write_atomic;

fn fixed(x: Option<f64>) -> String {
    x.map_or_else(String::new, |v| format!("{v:.6}"))
}

fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_owned()
    }
}

/// A row's counts, summaries and rates, in a CSV's column order.
type RowValues = (Vec<usize>, Vec<Option<Summary>>, Vec<Option<eval::Rate>>);

/// A CSV of one line per row: scenario, system and axis values, then `counts` (integers),
/// then mean, std, min, max and the 95 % interval of the mean of each of `summaries`, then
/// k, n, the rate and its 95 % Wilson interval of each of `rates`; `values` gives a row's
/// counts, summaries and rates in that order.
fn render_rows(
    agg: &Aggregate,
    counts: &[&str],
    summaries: &[&str],
    rates: &[&str],
    values: &dyn Fn(&Row) -> RowValues,
) -> String {
    let line = |fields: Vec<String>| {
        fields
            .iter()
            .map(|f| csv_field(f))
            .collect::<Vec<_>>()
            .join(",")
            + "\n"
    };
    let mut head = vec!["scenario".to_owned(), "system".to_owned()];
    head.extend(agg.axes.iter().map(|(p, _)| p.clone()));
    head.extend(counts.iter().map(|c| (*c).to_owned()));
    for m in summaries {
        head.extend(
            ["mean", "std", "min", "max", "ci95_low", "ci95_high"].map(|s| format!("{m}_{s}")),
        );
    }
    for m in rates {
        head.extend(["k", "n", "rate", "ci95_low", "ci95_high"].map(|s| format!("{m}_{s}")));
    }
    let mut out = line(head);
    for row in &agg.rows {
        let mut fields = vec![row.scenario.clone(), row.system.clone()];
        fields.extend(row.axes.iter().map(|(_, v)| v.clone()));
        let (n, stats, rates) = values(row);
        fields.extend(n.iter().map(usize::to_string));
        for s in stats {
            fields.extend([
                fixed(s.map(|s| s.mean)),
                fixed(s.and_then(|s| s.std)),
                fixed(s.map(|s| s.min)),
                fixed(s.map(|s| s.max)),
                fixed(s.and_then(|s| s.interval95).map(|i| i[0])),
                fixed(s.and_then(|s| s.interval95).map(|i| i[1])),
            ]);
        }
        for r in rates {
            fields.extend([
                r.map_or_else(String::new, |r| r.k.to_string()),
                r.map_or_else(String::new, |r| r.n.to_string()),
                fixed(r.map(|r| r.rate)),
                fixed(r.map(|r| r.interval95[0])),
                fixed(r.map(|r| r.interval95[1])),
            ]);
        }
        out += &line(fields);
    }
    out
}

/// `sweep.csv`.
pub fn render_csv(agg: &Aggregate) -> String {
    render_rows(
        agg,
        &["n_ok", "n_failed", "n_missing"],
        &[
            "ate_rmse_m",
            "loops_accepted",
            "loops_false",
            "wrong_joins",
            "sim3_scale",
            "drift_percent",
        ],
        &["false_join_runs"],
        &|row| {
            (
                vec![row.n_ok, row.n_failed, row.n_missing],
                vec![
                    row.ate_rmse_m,
                    row.loops_accepted,
                    row.loops_false,
                    row.wrong_joins,
                    row.sim3_scale,
                    row.drift_percent,
                ],
                vec![row.false_join_runs],
            )
        },
    )
}

/// `speed.csv`.
pub fn render_speed_csv(agg: &Aggregate) -> String {
    render_rows(
        agg,
        &["n"],
        &["realtime_factor", "cpu_s", "peak_rss_mb"],
        &[],
        &|row| {
            (
                vec![row.n_ok],
                vec![
                    row.speed.realtime_factor,
                    row.speed.cpu_s,
                    row.speed.peak_rss_mb,
                ],
                vec![],
            )
        },
    )
}

/// The headers of [`row_cells`].
pub const ROW_HEADERS: [&str; 10] = [
    "ok / failed / missing",
    "ATE RMSE (m)",
    "95 % CI",
    "min",
    "max",
    "loops accepted",
    "false loops",
    "wrong joins",
    "runs with a false loop or join",
    "RTF",
];

/// A row's cells after its axis values, as `sweep.md` and the sweep's page show them
/// ([`ROW_HEADERS`]): runs ok / failed / missing, ATE RMSE mean ± std, its 95 % interval,
/// min, max, loops accepted, false loops, wrong joins, the runs with a false loop or a
/// wrong join (k of n, the rate's 95 % Wilson interval), RTF.
pub fn row_cells(row: &Row) -> [String; 10] {
    let ate = |f: fn(&Summary) -> f64| {
        row.ate_rmse_m
            .map_or("–".into(), |s| format!("{:.3}", f(&s)))
    };
    [
        format!("{} / {} / {}", row.n_ok, row.n_failed, row.n_missing),
        pm(row.ate_rmse_m, 3),
        row.ate_rmse_m
            .and_then(|s| s.interval95)
            .map_or("–".into(), |[lo, hi]| format!("[{lo:.3}, {hi:.3}]")),
        ate(|s| s.min),
        ate(|s| s.max),
        pm(row.loops_accepted, 1),
        pm(row.loops_false, 1),
        pm(row.wrong_joins, 1),
        row.false_join_runs.map_or("–".into(), |r| {
            format!(
                "{} of {} [{:.2}, {:.2}]",
                r.k, r.n, r.interval95[0], r.interval95[1]
            )
        }),
        pm(row.speed.realtime_factor, 1),
    ]
}

/// Each failed run as `scenario system key=value…: seed s: reason`.
pub fn failure_lines(agg: &Aggregate) -> Vec<String> {
    agg.rows
        .iter()
        .flat_map(|r| {
            r.failures.iter().map(move |f| {
                let point: Vec<String> = r.axes.iter().map(|(p, v)| format!("{p}={v}")).collect();
                format!("{} {} {}: {f}", r.scenario, r.system, point.join(" "))
            })
        })
        .collect()
}

/// `mean ± std` with `decimals` (the mean alone for one run, `–` for none).
pub fn pm(s: Option<Summary>, decimals: usize) -> String {
    match s {
        None => "–".to_owned(),
        Some(Summary {
            mean, std: None, ..
        }) => format!("{mean:.decimals$}"),
        Some(Summary {
            mean,
            std: Some(sd),
            ..
        }) => format!("{mean:.decimals$} ± {sd:.decimals$}"),
    }
}

/// `sweep.md`.
pub fn render_markdown(agg: &Aggregate) -> String {
    let mut md = String::from("# Sweep\n\n");
    let _ = writeln!(
        md,
        "Seeds: {} ({} per cell). Mean ± sample standard deviation over the seeds, and the \
         95 % t interval of the mean; ATE is the RMSE of the translation error after \
         alignment, in metres. Runs with a false loop or join: of the ok runs, those with a \
         false accepted loop or a wrong join of the final map, with the 95 % Wilson \
         interval of the rate (ten runs tell only large differences apart).\n",
        agg.seeds
            .iter()
            .map(u64::to_string)
            .collect::<Vec<_>>()
            .join(", "),
        agg.seeds.len()
    );
    for (path, values) in &agg.axes {
        let _ = writeln!(md, "- `{path}`: {}", values.join(", "));
    }
    if !agg.axes.is_empty() {
        md.push('\n');
    }
    for scenario in &agg.scenarios {
        let _ = writeln!(md, "## {scenario}\n");
        let mut head = "| system |".to_owned();
        let mut rule = "|---|".to_owned();
        for (path, _) in &agg.axes {
            head += &format!(" {path} |");
            rule += "---|";
        }
        for h in ROW_HEADERS {
            head += &format!(" {h} |");
            rule += "---|";
        }
        let _ = writeln!(md, "{head}\n{rule}");
        for row in agg.mapping_rows(scenario) {
            let mut line = format!("| {} |", row.system);
            for (_, v) in &row.axes {
                line += &format!(" {v} |");
            }
            let _ = writeln!(md, "{line} {} |", row_cells(row).join(" | "));
        }
        md.push('\n');
        for (path, values) in &agg.axes {
            if values.len() > 1 {
                let _ = writeln!(
                    md,
                    "![ATE against {path}](plots/{}.svg)\n",
                    plot_stem(scenario, path)
                );
            }
        }
    }
    md += &render_localization(agg);
    let failed: Vec<String> = failure_lines(agg)
        .iter()
        .map(|f| format!("- {f}"))
        .collect();
    if !failed.is_empty() {
        let _ = writeln!(md, "## Failed runs\n\n{}\n", failed.join("\n"));
    }
    if agg.builds.len() > 1 {
        let _ = writeln!(
            md,
            "**The runs were made by {} builds of vinebench** ({}): a study should not mix \
             them unless the simulator and the evaluation did not change between them.\n",
            agg.builds.len(),
            agg.builds.join(", ")
        );
    }
    let missing = agg.missing();
    if missing > 0 {
        let _ = writeln!(
            md,
            "**{missing} runs are missing**: the sweep has not finished (run it again to \
             complete it).\n"
        );
    }
    md
}

/// File stem of a plot: ASCII letters, digits, `.`, `-`, `_` kept, the rest `_`.
fn plot_stem(scenario: &str, axis: &str) -> String {
    let clean = |s: &str| -> String {
        s.chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() || matches!(c, '.' | '-' | '_') {
                    c
                } else {
                    '_'
                }
            })
            .collect()
    };
    format!("{}-ate-vs-{}", clean(scenario), clean(axis))
}

const PLOT_WIDTH_PX: u32 = 900;

/// Colours of the systems, in order (Okabe–Ito, distinguishable in colour blindness).
const COLOURS: [Rgb; 8] = [
    [0, 114, 178],
    [213, 94, 0],
    [0, 158, 115],
    [204, 121, 167],
    [230, 159, 0],
    [86, 180, 233],
    [0, 0, 0],
    [240, 228, 66],
];

/// Axis values by path, as TOML text.
type Point = Vec<(String, String)>;

/// The headers of [`localization_cells`].
pub const LOCALIZATION_HEADERS: [&str; 9] = [
    "ok / failed / missing",
    "success",
    "first localised (s)",
    "localised fraction",
    "ATE in map frame (m)",
    "false vs map",
    "false vs truth",
    "wrong lane (s)",
    "relocalised after (s)",
];

/// A localisation row's cells after its axis values ([`LOCALIZATION_HEADERS`]): runs ok /
/// failed / missing, the success rate (k of n and its 95 % Wilson interval), then mean ±
/// std over the runs of time to the first localised pose, share of time localised, the
/// localised poses' error in the map frame, false localisations (episodes per run) against
/// the map and the truth, time in a wrong lane and time to relocalise after a kidnapping.
pub fn localization_cells(row: &Row) -> [String; 9] {
    let l = row.localization.clone().unwrap_or_default();
    [
        format!("{} / {} / {}", row.n_ok, row.n_failed, row.n_missing),
        l.success.map_or("–".into(), |r| {
            format!(
                "{} of {} [{:.2}, {:.2}]",
                r.k, r.n, r.interval95[0], r.interval95[1]
            )
        }),
        pm(l.first_localized_s, 1),
        pm(l.localized_fraction, 2),
        pm(l.ate_map_frame_m, 3),
        pm(l.false_vs_map, 1),
        pm(l.false_vs_truth, 1),
        pm(l.wrong_lane_s, 1),
        pm(l.relocalized_after_s, 1),
    ]
}

/// The localisation rows as a Markdown section (empty without any).
fn render_localization(agg: &Aggregate) -> String {
    let rows: Vec<&Row> = agg
        .rows
        .iter()
        .filter(|r| r.localization.is_some())
        .collect();
    if rows.is_empty() {
        return String::new();
    }
    let mut md = String::from(
        "## Localisation\n\nRuns started from a map built by a mapping run of this sweep (the \
         label's `@` names the map's point of the crossed axes) or from the surveyed grid. \
         Success: the first correct pose within 10 m of travel. False localisations: \
         episodes flagged localised more than 0.5 m or 10° off. Mean ± sample standard \
         deviation over the runs.\n\n",
    );
    let mut head = "| scenario | system |".to_owned();
    let mut rule = "|---|---|".to_owned();
    for (path, _) in &agg.axes {
        head += &format!(" {path} |");
        rule += "---|";
    }
    for h in LOCALIZATION_HEADERS {
        head += &format!(" {h} |");
        rule += "---|";
    }
    let _ = writeln!(md, "{head}\n{rule}");
    for row in rows {
        let mut line = format!("| {} | {} |", row.scenario, row.system);
        for (_, v) in &row.axes {
            line += &format!(" {v} |");
        }
        let _ = writeln!(md, "{line} {} |", localization_cells(row).join(" | "));
    }
    md.push('\n');
    md
}

/// ATE RMSE (mean, error bars ± one sample std over the seeds) against axis `k` on
/// `scenario`: one line per system and value of the other axes (the system's colour,
/// lighter for each further value), set side by side so that error bars do not hide
/// each other; `None` if nothing to draw.
pub fn ate_chart(agg: &Aggregate, scenario: &str, k: usize) -> Option<Chart> {
    let (path, values) = &agg.axes[k];
    // One series per (system, point of the other axes).
    let mut series: BTreeMap<(usize, Point), Vec<(usize, Summary)>> = BTreeMap::new();
    for row in agg.mapping_rows(scenario) {
        let Some(s) = row.ate_rmse_m else { continue };
        let system = agg.systems.iter().position(|x| *x == row.system)?;
        let x = values.iter().position(|v| *v == row.axes[k].1)?;
        let mut others = row.axes.clone();
        others.remove(k);
        series.entry((system, others)).or_default().push((x, s));
    }
    if series.is_empty() {
        return None;
    }
    let mut chart = Chart::new(
        format!("{scenario}: ATE RMSE against {path}"),
        path.rsplit('.').next().unwrap_or(path).to_owned(),
        format!("ATE RMSE (m), mean ± std over {} seeds", agg.seeds.len()),
    );
    chart.x_categories = values.clone();
    chart.height = Height::Fixed(440);
    let many = series.len() as f64;
    for (j, ((system, others), points)) in series.iter().enumerate() {
        let variant = series
            .keys()
            .filter(|(s, _)| s == system)
            .position(|(_, o)| o == others)
            .unwrap_or(0);
        let base = COLOURS[system % COLOURS.len()];
        let lighten = 1.0 - 0.6f64.powi(variant as i32);
        let color =
            base.map(|c| (f64::from(c) + (255.0 - f64::from(c)) * lighten * 0.8).round() as u8);
        let offset = (j as f64 - (many - 1.0) / 2.0) * (0.3 / many).min(0.06);
        chart.marks.push(Mark::ErrorBars {
            points: points
                .iter()
                .map(|(x, s)| {
                    let sd = s.std.unwrap_or(0.0);
                    (
                        *x as f64 + offset,
                        (s.mean - sd).max(0.0),
                        s.mean,
                        s.mean + sd,
                    )
                })
                .collect(),
            color,
        });
        let mut name = agg.systems[*system].clone();
        if !others.is_empty() {
            // The key's last part: `plant_variation=1.0` for `vineyard.plant_variation`.
            let o: Vec<String> = others
                .iter()
                .map(|(p, v)| format!("{}={v}", p.rsplit('.').next().unwrap_or(p)))
                .collect();
            name += &format!(" ({})", o.join(", "));
        }
        chart
            .legend
            .push((Swatch::Line { color, width_px: 2 }, name));
    }
    let top = chart
        .marks
        .iter()
        .filter_map(|m| match m {
            Mark::ErrorBars { points, .. } => points.iter().map(|p| p.3).reduce(f64::max),
            _ => None,
        })
        .fold(0.0, f64::max);
    chart.y_range = Some((0.0, if top > 0.0 { top * 1.08 } else { 1.0 }));
    Some(chart)
}

/// Reads the aggregate back from `out`'s `sweep.json`, with the speed summaries from
/// `speed.csv` (whose rows are the aggregate's, in order).
pub fn read(out: &Path) -> anyhow::Result<Aggregate> {
    let path = out.join("sweep.json");
    let text = std::fs::read_to_string(&path).with_context(|| {
        format!(
            "{}: cannot read (aggregate the sweep first: vinebench sweep FILE --collect)",
            path.display()
        )
    })?;
    let mut agg: Aggregate = serde_json::from_str(&text)
        .with_context(|| format!("{}: not a sweep aggregate", path.display()))?;
    let speed = out.join("speed.csv");
    if let Ok(csv) = std::fs::read_to_string(&speed) {
        // scenario, system, axes…, n, then mean/std/min/max/ci95_low/ci95_high of RTF,
        // CPU s, peak RSS.
        let first = 2 + agg.axes.len() + 1;
        for (row, line) in agg.rows.iter_mut().zip(csv.lines().skip(1)) {
            let fields: Vec<&str> = line.split(',').collect();
            let summary = |k: usize| -> Option<Summary> {
                let at = |i: usize| {
                    fields
                        .get(first + 6 * k + i)
                        .and_then(|f| f.parse::<f64>().ok())
                };
                Some(Summary {
                    mean: at(0)?,
                    std: at(1),
                    min: at(2)?,
                    max: at(3)?,
                    interval95: at(4).zip(at(5)).map(|(lo, hi)| [lo, hi]),
                })
            };
            row.speed = Speed {
                realtime_factor: summary(0),
                cpu_s: summary(1),
                peak_rss_mb: summary(2),
            };
        }
    }
    Ok(agg)
}

/// Writes every aggregate file into `out` (each written whole, then renamed into place).
pub fn write(agg: &Aggregate, out: &Path) -> anyhow::Result<()> {
    write_atomic(
        &out.join("sweep.json"),
        (serde_json::to_string_pretty(agg)? + "\n").as_bytes(),
    )?;
    write_atomic(&out.join("sweep.csv"), render_csv(agg).as_bytes())?;
    write_atomic(&out.join("speed.csv"), render_speed_csv(agg).as_bytes())?;
    write_atomic(&out.join("sweep.md"), render_markdown(agg).as_bytes())?;
    let plots = out.join("plots");
    // Plots of an earlier aggregate that this one would not draw must not stay.
    if plots.exists() {
        std::fs::remove_dir_all(&plots).with_context(|| plots.display().to_string())?;
    }
    std::fs::create_dir_all(&plots).with_context(|| plots.display().to_string())?;
    for scenario in &agg.scenarios {
        for (k, (path, values)) in agg.axes.iter().enumerate() {
            if values.len() < 2 {
                continue;
            }
            if let Some(chart) = ate_chart(agg, scenario, k) {
                let stem = plot_stem(scenario, path);
                write_atomic(
                    &plots.join(format!("{stem}.svg")),
                    chart.to_svg(PLOT_WIDTH_PX)?.as_bytes(),
                )?;
                write_atomic(
                    &plots.join(format!("{stem}.png")),
                    &chart.to_png(PLOT_WIDTH_PX)?,
                )?;
            }
        }
    }
    // The page from the files just written, as `vinebench report` builds it, so that a
    // rebuild gives the same bytes (speed.csv rounds the speeds).
    super::html::write_sweep_report(out, &read(out)?)?;
    Ok(())
}
