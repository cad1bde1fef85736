//! `report.html`: one self-contained page per bench or sweep (styles inline, line plots
//! as inline SVG, maps and grids as PNG data URIs, no script, nothing fetched), so it
//! opens from disk, travels as one file and prints.
//!
//! A bench's page, from its folder alone ([`super::load::BenchResults`]):
//! - the paper's Table 2 layout with real-time factor and loops accepted / false, and the
//!   failed runs with their reasons;
//! - per scenario the top view of every system's aligned estimate over ground truth (the
//!   paper's Fig. 3), accepted loops as segments, true thin grey, false wider red;
//! - per system the map of the last scenario from above, coloured by height, with its
//!   trajectory (the paper's Fig. 4), and its occupancy grid when it writes one;
//! - per run (folded) the translation error against time, timing (real-time factors,
//!   latency p50 / p99 / max per kind of call, CPU time, peak memory), the accepted loops
//!   with their judgement, and the resolved `run.toml`.
//!
//! A sweep's page: its axes and seeds, the aggregate table and the ATE-against-axis plots.
//! Every byte is a function of the results (no clock), so rebuilding gives the same page.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::Context as _;
use eval::plot::Chart;

use super::figures::{MAX_LINE_POINTS, decimate, error_chart, grid_chart, map_chart};
use super::load::{BenchResults, LoadedRun};
use super::plot::{LoopSegment, Track, WIDTH_PX, scenario_chart};
use super::table::Table;
use super::{RunStatus, markdown};
use crate::results::aggregate::Aggregate;

/// The page's file name in a results folder.
pub const REPORT: &str = "report.html";
const MAP_WIDTH_PX: u32 = 620;
const RUN_WIDTH_PX: u32 = 900;

const STYLE: &str = "
body{font-family:'DejaVu Sans',Verdana,sans-serif;margin:0 auto;max-width:1280px;padding:0 24px 48px;color:#1a1a1a;line-height:1.45}
h1{margin:24px 0 4px}h2{border-bottom:1px solid #ccc;padding-bottom:4px;margin-top:36px}
nav a{margin-right:14px}
.scroll{overflow-x:auto}
table{border-collapse:collapse;font-size:13px;margin:8px 0}
th,td{border:1px solid #d0d0d0;padding:3px 7px;text-align:right;white-space:nowrap}
th{background:#f2f2f2}td.l,th.l{text-align:left}
tr.rule td{border-top:2px solid #888}tr.sep th{background:#dde6ee;font-size:14px}
td.failed{color:#b00000}
figure{margin:12px 0}figcaption{font-size:13px;color:#444;max-width:900px}
figure img,figure svg{max-width:100%;height:auto;border:1px solid #e4e4e4}
.grid2{display:flex;flex-wrap:wrap;gap:16px}
details{margin:6px 0;border:1px solid #e0e0e0;border-radius:4px;padding:4px 10px}
summary{cursor:pointer;font-weight:bold}
pre{background:#f7f7f7;padding:8px;overflow-x:auto;font-size:12px}
.note{color:#555;font-size:14px}.bad{color:#b00000}.good{color:#007a33}
";

/// HTML-escaped text.
pub(super) fn esc(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

/// Standard base64 with padding (RFC 4648 §4), for data URIs.
fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            *chunk.get(1).unwrap_or(&0),
            *chunk.get(2).unwrap_or(&0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(char::from(ALPHABET[(n >> (18 - 6 * k)) as usize & 63]));
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// An id for an HTML anchor: ASCII letters and digits kept, the rest `-`.
fn anchor(parts: &[&str]) -> String {
    parts
        .iter()
        .map(|p| {
            p.chars()
                .map(|c| if c.is_ascii_alphanumeric() { c } else { '-' })
                .collect::<String>()
        })
        .collect::<Vec<_>>()
        .join("-")
}

/// A chart as an inline SVG figure with a caption.
fn svg_figure(chart: &Chart, width: u32, caption: &str) -> anyhow::Result<String> {
    let svg = chart.to_svg(width)?;
    // The page sizes the picture: keep the view box, let CSS scale it.
    let svg = svg.replacen(
        "<svg ",
        &format!("<svg role=\"img\" aria-label=\"{}\" ", esc(&chart.title)),
        1,
    );
    Ok(format!(
        "<figure>{svg}<figcaption>{}</figcaption></figure>\n",
        esc(caption)
    ))
}

/// A chart as a PNG data-URI figure with a caption.
fn png_figure(chart: &Chart, width: u32, caption: &str) -> anyhow::Result<String> {
    let png = chart.to_png(width)?;
    Ok(format!(
        "<figure><img alt=\"{}\" src=\"data:image/png;base64,{}\"><figcaption>{}</figcaption></figure>\n",
        esc(&chart.title),
        base64(&png),
        esc(caption)
    ))
}

fn page(title: &str, body: &str) -> String {
    format!(
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n<title>{}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n{body}</body>\n</html>\n",
        esc(title)
    )
}

/// Writes `report.html` into `dir` whole (a temporary name, then renamed) and returns its
/// size in bytes.
pub(super) fn write_page(dir: &Path, html: &str) -> anyhow::Result<u64> {
    let path = dir.join(REPORT);
    let tmp = dir.join(format!(".{REPORT}.tmp"));
    std::fs::write(&tmp, html).with_context(|| format!("writing {}", tmp.display()))?;
    std::fs::rename(&tmp, &path).with_context(|| format!("writing {}", path.display()))?;
    Ok(html.len() as u64)
}

/// Builds and writes the report of the bench results in `dir` (titled `name`, the
/// folder's final name); returns its size in bytes.
pub fn write_bench_report(dir: &Path, name: &str) -> anyhow::Result<u64> {
    let results = BenchResults::load(dir)?;
    write_page(dir, &bench_page(&results, name)?)
}

/// The page of a bench.
pub fn bench_page(results: &BenchResults, name: &str) -> anyhow::Result<String> {
    let records: Vec<_> = results.runs.iter().map(|r| r.record.clone()).collect();
    let reference = super::reference::Reference::in_folder(&results.dir)?;
    let table = Table::new(&results.scenarios, &results.plugins, &records)?
        .with_reference(reference.as_ref());
    let mut body = String::new();
    let _ = writeln!(body, "<h1>vinebench: {}</h1>", esc(name));
    let ok = records.iter().filter(|r| r.status == RunStatus::Ok).count();
    let _ = writeln!(
        body,
        "<p class=\"note\">{} scenarios × {} systems: {} runs, {} ok, {} failed.</p>",
        results.scenarios.len(),
        results.plugins.len(),
        records.len(),
        ok,
        records.len() - ok
    );
    if let Some(note) = table.cut_note() {
        let _ = writeln!(body, "<p class=\"bad\">{}</p>", esc(&note));
    }
    body.push_str("<nav><a href=\"#table\">Table</a>");
    for s in &results.scenarios {
        let _ = write!(
            body,
            "<a href=\"#{}\">{}</a>",
            anchor(&["scenario", s]),
            esc(s)
        );
    }
    body.push_str("<a href=\"#maps\">Maps</a><a href=\"#runs\">Runs</a></nav>\n");

    body.push_str("<section id=\"table\"><h2>Absolute trajectory error</h2>\n");
    body.push_str(&table_html(&table));
    body.push_str("</section>\n");

    for scenario in &results.scenarios {
        let _ = writeln!(
            body,
            "<section id=\"{}\"><h2>{}</h2>",
            anchor(&["scenario", scenario]),
            esc(scenario)
        );
        body.push_str(&scenario_figure(results, scenario)?);
        body.push_str("</section>\n");
    }

    let map_scenario = results
        .scenarios
        .iter()
        .find(|s| s.eq_ignore_ascii_case("s3"))
        .or(results.scenarios.last());
    body.push_str("<section id=\"maps\"><h2>Maps</h2>\n");
    if let Some(scenario) = map_scenario {
        let _ = writeln!(
            body,
            "<p class=\"note\">Each system's map of {} from above, in its own map frame, with its trajectory (the paper's Fig. 4); the occupancy grid where it writes one.</p>",
            esc(scenario)
        );
        let mut any = false;
        for run in results
            .runs
            .iter()
            .filter(|r| &r.record.scenario == scenario)
        {
            let Some(detail) = &run.detail else { continue };
            let plugin = &run.record.plugin;
            let map = map_chart(
                &format!("{scenario} / {plugin}: map, coloured by height"),
                &run.dir,
                detail,
            )?;
            let grid = grid_chart(
                &format!("{scenario} / {plugin}: occupancy grid"),
                &run.dir,
                detail,
            )?;
            if map.is_none() && grid.is_none() {
                continue;
            }
            any = true;
            let _ = writeln!(
                body,
                "<h3 id=\"{}\">{}</h3><div class=\"grid2\">",
                anchor(&["map", plugin]),
                esc(plugin)
            );
            if let Some(chart) = map {
                body.push_str(&png_figure(
                    &chart,
                    MAP_WIDTH_PX,
                    &format!("{plugin}'s map.ply on {scenario}"),
                )?);
            }
            if let Some(chart) = grid {
                body.push_str(&png_figure(
                    &chart,
                    MAP_WIDTH_PX,
                    &format!("{plugin}'s grid.pgm on {scenario}"),
                )?);
            }
            body.push_str("</div>\n");
        }
        if !any {
            body.push_str("<p>No system wrote a map on this scenario.</p>\n");
        }
    }
    body.push_str("</section>\n");

    body.push_str("<section id=\"runs\"><h2>Runs</h2>\n");
    for run in &results.runs {
        body.push_str(&run_html(run)?);
    }
    body.push_str("</section>\n");
    Ok(page(&format!("vinebench: {name}"), &body))
}

/// The paper-style table (Table 2): per scenario a block with a header row naming it,
/// a row naming the systems and the statistic, RTF and loop rows, so that a bench of many
/// systems stays readable without scrolling sideways; failed runs below.
fn table_html(table: &Table) -> String {
    let rows = table.rows();
    let mut h = String::from("<div class=\"scroll\"><table>\n");
    for (scenario, range) in table.groups() {
        let _ = writeln!(
            h,
            "<tr class=\"sep\"><th class=\"l\" colspan=\"{}\">{}</th></tr>",
            range.len() + 1,
            esc(scenario)
        );
        h.push_str("<tr><th class=\"l\">system</th>");
        for c in &table.columns[range.clone()] {
            let _ = write!(h, "<th>{}</th>", esc(&c.run.plugin));
        }
        h.push_str("</tr>\n");
        for (k, row) in rows.iter().enumerate() {
            let class = if k == super::table::ERROR_ROWS {
                " class=\"rule\""
            } else {
                ""
            };
            let _ = write!(h, "<tr{class}><td class=\"l\">{}</td>", esc(row.label));
            for i in range.clone() {
                let text = row.text(i);
                let class = if text == "failed" {
                    " class=\"failed\""
                } else {
                    ""
                };
                let _ = write!(h, "<td{class}>{}</td>", esc(&text));
            }
            h.push_str("</tr>\n");
        }
    }
    h.push_str("</table></div>\n");
    let _ = writeln!(h, "<p class=\"note\">{}</p>", esc(markdown::CAPTION));
    if table.reference.is_some() {
        let _ = writeln!(h, "<p class=\"note\">{}</p>", esc(markdown::PAPER_CAPTION));
    }
    let failures: Vec<_> = table.failures().collect();
    if !failures.is_empty() {
        h.push_str("<p>Failed runs:</p><ul>\n");
        for (scenario, plugin, reason) in failures {
            let _ = writeln!(
                h,
                "<li class=\"bad\">{} / {}: {}</li>",
                esc(scenario),
                esc(plugin),
                esc(reason)
            );
        }
        h.push_str("</ul>\n");
    }
    h
}

/// The scenario's top view with every system and its loops.
fn scenario_figure(results: &BenchResults, scenario: &str) -> anyhow::Result<String> {
    let runs: Vec<&LoadedRun> = results
        .runs
        .iter()
        .filter(|r| r.record.scenario == scenario)
        .collect();
    let truth = runs
        .iter()
        .find_map(|r| r.detail.as_ref())
        .map(|d| decimate(&d.groundtruth_xy, MAX_LINE_POINTS))
        .unwrap_or_default();
    let estimates: Vec<Vec<(f64, f64)>> = runs
        .iter()
        .map(|r| decimate(&r.record.estimate_xy, MAX_LINE_POINTS))
        .collect();
    let loops: Vec<Vec<LoopSegment>> = runs
        .iter()
        .map(|r| {
            r.detail
                .as_ref()
                .map(|d| d.loops.iter().filter_map(|l| l.segment).collect())
                .unwrap_or_default()
        })
        .collect();
    let tracks: Vec<Track> = runs
        .iter()
        .enumerate()
        .map(|(i, r)| Track {
            plugin: &r.record.plugin,
            plugin_index: results
                .plugins
                .iter()
                .position(|p| *p == r.record.plugin)
                .unwrap_or(i),
            outcome: match &r.record.status {
                RunStatus::Ok => Ok((estimates[i].as_slice(), loops[i].as_slice())),
                RunStatus::Failed(reason) => Err(reason.as_str()),
            },
        })
        .collect();
    if truth.is_empty() {
        return Ok("<p>No run of this scenario finished: nothing to draw.</p>\n".into());
    }
    let chart = scenario_chart(scenario, &truth, &tracks);
    let per_system: Vec<String> = runs
        .iter()
        .zip(&loops)
        .filter(|(_, l)| !l.is_empty())
        .map(|(r, l)| {
            let false_ = l.iter().filter(|s| !s.true_loop).count();
            format!("{} {} ({false_} false)", r.record.plugin, l.len())
        })
        .collect();
    let loops_text = if per_system.is_empty() {
        "no accepted loop closure to draw".to_owned()
    } else {
        format!(
            "accepted loop closures drawn between the poses they join on the system's own estimate, grey if ground truth confirms them, red if not: {}",
            per_system.join(", ")
        )
    };
    svg_figure(
        &chart,
        WIDTH_PX,
        &format!(
            "Top view of every system's final estimate after alignment to ground truth (black); {loops_text}."
        ),
    )
}

fn fmt_opt(v: Option<f64>, decimals: usize) -> String {
    v.filter(|v| v.is_finite())
        .map_or_else(|| "n/a".to_owned(), |v| format!("{v:.decimals$}"))
}

/// One run, folded: status and scores in the summary line, figures and files inside.
fn run_html(run: &LoadedRun) -> anyhow::Result<String> {
    let r = &run.record;
    let mut h = String::new();
    let headline = match (&r.status, &r.ape) {
        (RunStatus::Failed(reason), _) => {
            format!("<span class=\"bad\">failed: {}</span>", esc(reason))
        }
        (RunStatus::Ok, Some(ape)) => format!(
            "ATE RMSE {:.3} m, RTF {}, loops {} ({} false)",
            ape.rmse,
            fmt_opt(r.realtime_factor, 1),
            r.loops.map_or(0, |l| l.accepted),
            r.loops.map_or(0, |l| l.accepted_false)
        ),
        (RunStatus::Ok, None) => "ok".into(),
    };
    let _ = writeln!(
        h,
        "<details id=\"{}\"><summary>{} / {}: {headline}</summary>",
        anchor(&["run", &r.scenario, &r.plugin]),
        esc(&r.scenario),
        esc(&r.plugin)
    );
    if let Some(detail) = &run.detail
        && let Some(chart) = error_chart(
            &format!(
                "{} / {}: translation error against time",
                r.scenario, r.plugin
            ),
            detail,
        )
    {
        h.push_str(&svg_figure(
            &chart,
            RUN_WIDTH_PX,
            &format!(
                "APE translation of each pose after {} alignment.",
                detail.alignment
            ),
        )?);
    }
    if let Some(t) = &run.timing {
        h.push_str("<table><tr><th class=\"l\">timing</th><th>value</th></tr>\n");
        let rows = [
            (
                "real-time factor (the system's calls)",
                fmt_opt(Some(t.realtime_factor_plugin), 2),
            ),
            (
                "real-time factor (wall clock)",
                fmt_opt(Some(t.realtime_factor), 2),
            ),
            ("simulated (s)", format!("{:.1}", t.simulated_s)),
            ("wall (s)", format!("{:.1}", t.wall_s)),
            ("in the system's calls (s)", fmt_opt(Some(t.plugin_s), 1)),
            ("CPU (s)", fmt_opt(t.cpu_s, 1)),
            ("peak memory (MB)", fmt_opt(t.peak_rss_mb, 1)),
            ("data", t.source.clone()),
        ];
        for (label, value) in rows {
            let _ = writeln!(
                h,
                "<tr><td class=\"l\">{label}</td><td>{}</td></tr>",
                esc(&value)
            );
        }
        h.push_str("</table>\n");
        if !t.latency.is_empty() {
            h.push_str("<table><tr><th class=\"l\">call</th><th>calls</th><th>p50 (ms)</th><th>p99 (ms)</th><th>max (ms)</th><th>total (s)</th></tr>\n");
            for (name, l) in &t.latency {
                let _ = writeln!(
                    h,
                    "<tr><td class=\"l\">{}</td><td>{}</td><td>{:.3}</td><td>{:.3}</td><td>{:.3}</td><td>{:.3}</td></tr>",
                    esc(name),
                    l.calls,
                    l.p50_ms,
                    l.p99_ms,
                    l.max_ms,
                    l.total_s
                );
            }
            h.push_str("</table>\n");
        }
    }
    if let Some(detail) = &run.detail
        && !detail.loops.is_empty()
    {
        h.push_str("<table><tr><th>accepted at (s)</th><th>joins (s)</th><th class=\"l\">judgement</th><th>ground-truth distance (m)</th><th class=\"l\">detail</th></tr>\n");
        for l in &detail.loops {
            let joins = l.stamps_ns.map_or("n/a".into(), |[a, b]| {
                format!("{:.1} – {:.1}", a as f64 * 1e-9, b as f64 * 1e-9)
            });
            let judgement = match l.true_loop {
                Some(true) => "<span class=\"good\">true</span>",
                Some(false) => "<span class=\"bad\">false</span>",
                None => "not judged",
            };
            let _ = writeln!(
                h,
                "<tr><td>{:.1}</td><td>{joins}</td><td class=\"l\">{judgement}</td><td>{}</td><td class=\"l\">{}</td></tr>",
                l.stamp_ns as f64 * 1e-9,
                fmt_opt(l.gt_distance_m, 2),
                esc(&l.detail)
            );
        }
        h.push_str("</table>\n");
    }
    if let Some(toml) = &run.run_toml {
        let _ = writeln!(
            h,
            "<details><summary>run.toml</summary><pre>{}</pre></details>",
            esc(toml)
        );
    }
    let folder = format!("{}/{}/", r.scenario, r.plugin);
    let _ = writeln!(
        h,
        "<p class=\"note\">Files: <a href=\"{}\">{}</a></p>",
        esc(&folder),
        esc(&folder)
    );
    h.push_str("</details>\n");
    Ok(h)
}

/// The page of a sweep from its aggregate and plots.
pub fn sweep_page(name: &str, agg: &Aggregate) -> anyhow::Result<String> {
    use super::sweep::{ate_chart, failure_lines, row_cells};
    let mut body = String::new();
    let _ = writeln!(body, "<h1>vinebench sweep: {}</h1>", esc(name));
    let seeds: Vec<String> = agg.seeds.iter().map(u64::to_string).collect();
    let _ = writeln!(
        body,
        "<p class=\"note\">Seeds {} ({} per cell): mean ± sample standard deviation over the seeds. ATE is the RMSE of the translation error after alignment, in metres.</p><ul>",
        esc(&seeds.join(", ")),
        agg.seeds.len()
    );
    for (path, values) in &agg.axes {
        let _ = writeln!(
            body,
            "<li><code>{}</code>: {}</li>",
            esc(path),
            esc(&values.join(", "))
        );
    }
    body.push_str("</ul>\n");
    if agg.builds.len() > 1 {
        let _ = writeln!(
            body,
            "<p class=\"bad\">The runs were made by {} different vinebench builds ({}): a change to the simulator between them would mix results.</p>",
            agg.builds.len(),
            esc(&agg.builds.join(", "))
        );
    }
    let missing = agg.missing();
    if missing > 0 {
        let _ = writeln!(
            body,
            "<p class=\"bad\">{missing} runs are missing: the aggregate is partial.</p>"
        );
    }
    for scenario in &agg.scenarios {
        let _ = writeln!(
            body,
            "<section id=\"{}\"><h2>{}</h2>",
            anchor(&["scenario", scenario]),
            esc(scenario)
        );
        body.push_str("<div class=\"scroll\"><table><tr><th class=\"l\">system</th>");
        for (path, _) in &agg.axes {
            let _ = write!(body, "<th>{}</th>", esc(path));
        }
        body.push_str("<th>ok / failed / missing</th><th>ATE RMSE (m)</th><th>min</th><th>max</th><th>loops accepted</th><th>false loops</th><th>RTF</th></tr>\n");
        for row in agg.rows.iter().filter(|r| &r.scenario == scenario) {
            let _ = write!(body, "<tr><td class=\"l\">{}</td>", esc(&row.system));
            for (_, v) in &row.axes {
                let _ = write!(body, "<td>{}</td>", esc(v));
            }
            for cell in row_cells(row) {
                let _ = write!(body, "<td>{}</td>", esc(&cell));
            }
            body.push_str("</tr>\n");
        }
        body.push_str("</table></div>\n");
        for (k, (path, values)) in agg.axes.iter().enumerate() {
            if values.len() < 2 {
                continue;
            }
            if let Some(chart) = ate_chart(agg, scenario, k) {
                body.push_str(&svg_figure(
                    &chart,
                    900,
                    &format!("ATE RMSE against {path}: mean with ± one standard deviation over the seeds."),
                )?);
            }
        }
        body.push_str("</section>\n");
    }
    let failures = failure_lines(agg);
    if !failures.is_empty() {
        body.push_str("<section id=\"failed\"><h2>Failed runs</h2><ul>\n");
        for f in failures {
            let _ = writeln!(body, "<li class=\"bad\">{}</li>", esc(&f));
        }
        body.push_str("</ul></section>\n");
    }
    Ok(page(&format!("vinebench sweep: {name}"), &body))
}

/// Writes a sweep's `report.html` into `dir`; returns its size in bytes.
pub fn write_sweep_report(dir: &Path, agg: &Aggregate) -> anyhow::Result<u64> {
    let name = dir
        .canonicalize()
        .ok()
        .and_then(|d| d.file_name().map(|n| n.to_string_lossy().into_owned()))
        .unwrap_or_else(|| "sweep".into());
    write_page(dir, &sweep_page(&name, agg)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_rfc_4648_vectors() {
        for (input, expected) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(base64(input.as_bytes()), expected, "{input:?}");
        }
    }

    #[test]
    fn text_is_escaped() {
        assert_eq!(
            esc("<a href=\"x\">&'"),
            "&lt;a href=&quot;x&quot;&gt;&amp;&#39;"
        );
        assert_eq!(anchor(&["s3", "lio sam"]), "s3-lio-sam");
    }
}
