//! A bench's page: the table, the trajectories per scenario, the maps per system, and every
//! run folded.

use super::*;
use crate::results::JudgedBy;
use crate::results::PairKind;

/// Builds and writes the report of the bench results in `dir` (titled `name`, the
/// folder's final name); returns its size in bytes.
pub fn write_bench_report(dir: &Path, name: &str) -> anyhow::Result<u64> {
    let results = BenchResults::load(dir)?;
    write_page(dir, &bench_page(&results, name)?)
}

/// The page of a bench.
pub fn bench_page(results: &BenchResults, name: &str) -> anyhow::Result<String> {
    let records: Vec<_> = results.runs.iter().map(|r| r.record.clone()).collect();
    let reference = crate::report::reference::Reference::in_folder(&results.dir)?;
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
pub(super) fn table_html(table: &Table) -> String {
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
            let class = if k == crate::report::table::ERROR_ROWS {
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
pub(super) fn scenario_figure(results: &BenchResults, scenario: &str) -> anyhow::Result<String> {
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
                .map(|d| {
                    d.loops
                        .iter()
                        .filter_map(|l| l.segment)
                        .chain(d.wrong_join_segments())
                        .collect()
                })
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
            let joins = l.iter().filter(|s| s.wrong_join).count();
            let loops = l.len() - joins;
            let false_ = l.iter().filter(|s| !s.true_loop && !s.wrong_join).count();
            format!(
                "{} {loops} ({false_} false), {joins} wrong joins",
                r.record.plugin
            )
        })
        .collect();
    let loops_text = if per_system.is_empty() {
        "no accepted loop closure or wrong join to draw".to_owned()
    } else {
        format!(
            "accepted loop closures drawn between the poses they join on the system's own estimate, grey if ground truth confirms them, red if not; wrong joins of the final map (whatever the system reported) in orange between the two true places they join: {}",
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

pub(super) fn fmt_opt(v: Option<f64>, decimals: usize) -> String {
    v.filter(|v| v.is_finite())
        .map_or_else(|| "n/a".to_owned(), |v| format!("{v:.decimals$}"))
}

/// One run, folded: status and scores in the summary line, figures and files inside.
pub(super) fn run_html(run: &LoadedRun) -> anyhow::Result<String> {
    let r = &run.record;
    let mut h = String::new();
    let headline = match (&r.status, &r.ape) {
        (RunStatus::Failed(reason), _) => {
            format!("<span class=\"bad\">failed: {}</span>", esc(reason))
        }
        (RunStatus::Ok, Some(ape)) => format!(
            "ATE RMSE {:.3} m, RTF {}, loops {} ({} false), wrong joins {}",
            ape.rmse,
            fmt_opt(r.realtime_factor, 1),
            r.loops.map_or(0, |l| l.accepted),
            r.loops.map_or(0, |l| l.accepted_false),
            r.joins.map_or_else(
                || "n/a".to_owned(),
                |j| format!("{} ({} silent)", j.wrong_joins, j.silent)
            )
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
    if let Some(detail) = &run.detail
        && let Some(epochs) = &detail.gnss
        && let Some(svg) =
            super::super::figures::gnss_svg(&detail.groundtruth_xy, epochs, f64::from(RUN_WIDTH_PX))
    {
        let _ = writeln!(
            h,
            "<figure>{svg}<figcaption>The GNSS fixes fed to the system along the true route, \
             coloured by fix status (issue 47's fix-quality map).</figcaption></figure>"
        );
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
        h.push_str("<table><tr><th>accepted at (s)</th><th>joins (s)</th><th class=\"l\">judgement</th><th class=\"l\">judged by</th><th>ground-truth distance (m)</th><th class=\"l\">detail</th></tr>\n");
        for l in &detail.loops {
            let joins = l.stamps_ns.map_or("n/a".into(), |[a, b]| {
                format!("{:.1} – {:.1}", a as f64 * 1e-9, b as f64 * 1e-9)
            });
            let judgement = match l.true_loop {
                Some(true) => "<span class=\"good\">true</span>",
                Some(false) => "<span class=\"bad\">false</span>",
                None => "not judged",
            };
            let judged_by = match l.judged_by {
                Some(JudgedBy::Stamps) => "its stamps",
                Some(JudgedBy::RelativePose) => "its relative pose",
                Some(JudgedBy::FinalMap) => "the final map",
                Some(JudgedBy::OnlineError) => "the online error",
                None => "",
            };
            let _ = writeln!(
                h,
                "<tr><td>{:.1}</td><td>{joins}</td><td class=\"l\">{judgement}</td><td class=\"l\">{judged_by}</td><td>{}</td><td class=\"l\">{}</td></tr>",
                l.stamp_ns as f64 * 1e-9,
                fmt_opt(l.gt_distance_m, 2),
                esc(&l.detail)
            );
        }
        h.push_str("</table>\n");
    }
    if let Some(joins) = run.detail.as_ref().and_then(|d| d.joins.as_ref())
        && !joins.report.wrong_joins.is_empty()
    {
        h.push_str("<table><tr><th>later stretch (s)</th><th>earlier stretch (s)</th><th>travel (m)</th><th>apart in the estimate (m)</th><th>apart in truth (m)</th><th class=\"l\">true places (x, y)</th><th class=\"l\">explained by</th></tr>\n");
        for (k, e) in joins.report.wrong_joins.iter().enumerate() {
            let explained = if joins.silent.contains(&k) {
                "<span class=\"bad\">nothing (silent)</span>"
            } else {
                "an accepted loop"
            };
            let _ = writeln!(
                h,
                "<tr><td>{:.1} – {:.1}</td><td>{:.1} – {:.1}</td><td>{:.1}</td><td>{:.2}</td><td>{:.2}</td><td class=\"l\">({:.1}, {:.1}) and ({:.1}, {:.1})</td><td class=\"l\">{explained}</td></tr>",
                e.later_s[0],
                e.later_s[1],
                e.earlier_s[0],
                e.earlier_s[1],
                e.travel_m,
                e.estimate_distance_m,
                e.truth_distance_m,
                e.later_place[0],
                e.later_place[1],
                e.earlier_place[0],
                e.earlier_place[1],
            );
        }
        h.push_str("</table>\n<p class=\"note\">Wrong joins of the final map: stretches the estimate keeps within 1 m over 3 m or more that ground truth keeps more than 2.5 m apart (joins.json).</p>\n");
    }
    if let Some(frames) = run.detail.as_ref().and_then(|d| d.frames.as_ref())
        && !frames.pairs.is_empty()
    {
        h.push_str("<div class=\"frames\">\n");
        for pair in &frames.pairs {
            let what = match pair.kind {
                PairKind::FalseLoop => format!("false loop (events.json #{})", pair.index),
                PairKind::TrueLoop => format!("true loop (events.json #{})", pair.index),
                PairKind::WrongJoin => format!("wrong join #{} of the final map", pair.index),
            };
            let img = |h: &mut String, file: &str| {
                let _ = write!(
                    h,
                    "<img src=\"{}/{}/{}\" alt=\"{}\" loading=\"lazy\">",
                    esc(&r.scenario),
                    esc(&r.plugin),
                    esc(file),
                    esc(file)
                );
            };
            let (later_s, earlier_s) = (
                pair.stamps_ns[0] as f64 * 1e-9,
                pair.stamps_ns[1] as f64 * 1e-9,
            );
            if !pair.files.is_empty() {
                let _ = write!(h, "<figure class=\"pair\">");
                for file in &pair.files {
                    img(&mut h, file);
                }
                let _ = writeln!(
                    h,
                    "<figcaption>{}: the colour frames the system was given at {later_s:.2} s (left) and {earlier_s:.2} s (right), rendered again from the run's world and seed.</figcaption></figure>",
                    esc(&what)
                );
            }
            if let Some(file) = &pair.matches {
                let _ = write!(h, "<figure class=\"pair\">");
                img(&mut h, file);
                let mut on: Vec<(&String, &usize)> = pair.matched_surfaces.iter().collect();
                on.sort_by(|a, b| b.1.cmp(a.1).then(a.0.cmp(b.0)));
                let on: Vec<String> = on.iter().map(|(k, n)| format!("{k} {n}")).collect();
                let on = if on.is_empty() {
                    String::new()
                } else {
                    format!(
                        " What they lie on (later/earlier, by the simulator's rays): {}.",
                        on.join(", ")
                    )
                };
                let _ = writeln!(
                    h,
                    "<figcaption>{}: the keypoints the system matched between the two frames (its event's loop_matches).{}</figcaption></figure>",
                    esc(&what),
                    esc(&on)
                );
            }
            if !pair.scans.is_empty() {
                let _ = write!(h, "<figure class=\"pair\">");
                for file in &pair.scans {
                    img(&mut h, file);
                }
                let overlap = if pair.scan_overlap.len() == pair.scans.len() {
                    let shares: Vec<String> = pair
                        .scan_overlap
                        .iter()
                        .map(|v| format!("{:.0} %", 100.0 * v))
                        .collect();
                    format!(
                        " Share of the later sweep's points within 0.2 m of the earlier's: {}.",
                        shares.join(" and ")
                    )
                } else {
                    String::new()
                };
                let _ = writeln!(
                    h,
                    "<figcaption>{}: the lidar sweeps at {later_s:.2} s (orange) and {earlier_s:.2} s (blue) from above, the later placed at the estimate's relative pose (left, where the run has one) and at ground truth's (right); cast again from the run's world without range noise, ground and points beyond 25 m left out.{}</figcaption></figure>",
                    esc(&what),
                    esc(&overlap)
                );
            }
        }
        h.push_str("</div>\n");
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
