//! A sweep's page: its axes and seeds, the aggregate table and the ATE-against-axis plots.

use super::*;

/// The page of a sweep from its aggregate and plots.
pub fn sweep_page(name: &str, agg: &Aggregate) -> anyhow::Result<String> {
    use crate::report::sweep::{ate_chart, failure_lines, row_cells};
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
        for h in crate::report::sweep::ROW_HEADERS {
            let _ = write!(body, "<th>{}</th>", esc(h));
        }
        body.push_str("</tr>\n");
        for row in agg.mapping_rows(scenario) {
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
    let localizing: Vec<_> = agg
        .rows
        .iter()
        .filter(|r| r.localization.is_some())
        .collect();
    if !localizing.is_empty() {
        body.push_str(
            "<section id=\"localization\"><h2>Localisation</h2><p>Runs started from a map \
             built by a mapping run of this sweep (the label's <code>@</code> names the map's \
             point of the crossed axes) or from the surveyed grid; success is the first correct \
             pose within 10 m of travel, a false localisation an episode flagged localised more \
             than 0.5 m or 10° off.</p>\n<div class=\"scroll\"><table><tr><th class=\"l\">\
             scenario</th><th class=\"l\">system</th>",
        );
        for (path, _) in &agg.axes {
            let _ = write!(body, "<th>{}</th>", esc(path));
        }
        for h in crate::report::sweep::LOCALIZATION_HEADERS {
            let _ = write!(body, "<th>{}</th>", esc(h));
        }
        body.push_str("</tr>\n");
        for row in localizing {
            let _ = write!(
                body,
                "<tr><td class=\"l\">{}</td><td class=\"l\">{}</td>",
                esc(&row.scenario),
                esc(&row.system)
            );
            for (_, v) in &row.axes {
                let _ = write!(body, "<td>{}</td>", esc(v));
            }
            for cell in crate::report::sweep::localization_cells(row) {
                let _ = write!(body, "<td>{}</td>", esc(&cell));
            }
            body.push_str("</tr>\n");
        }
        body.push_str("</table></div></section>\n");
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
