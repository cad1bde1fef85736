//! The table as a LaTeX `tabular` with booktabs rules (`\usepackage{booktabs}`), ready
//! to `\input` inside a `table` environment: scenarios as `\multicolumn` headers over
//! their systems, a footnote line naming the failed runs and why they failed, and one
//! saying the routes were cut when they were (`--max-time`).

use std::fmt::Write as _;

use super::table::Table;

/// `text` with LaTeX's special characters escaped.
pub(super) fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '_' | '&' | '%' | '#' | '$' | '{' | '}' => {
                out.push('\\');
                out.push(c);
            }
            '\\' => out.push_str("\\textbackslash{}"),
            '~' => out.push_str("\\textasciitilde{}"),
            '^' => out.push_str("\\textasciicircum{}"),
            _ => out.push(c),
        }
    }
    out
}

/// The LaTeX of `table`.
pub(super) fn render(table: &Table) -> String {
    let n = table.columns.len();
    let groups = table.groups();
    let mut out = String::from(
        "% vinebench benchmark table; needs \\usepackage{booktabs}.\n\
         % APE translation after alignment in metres; scale: of a Sim(3) alignment;\n\
         % drift: metres per 100 m over 5-20 m segments; RTF: simulated seconds per second\n\
         % spent in the system's calls; loops: loop closures accepted; false loops: of those,\n\
         % the ones ground truth shows false (a measured relative pose off by more than 0.5 m\n\
         % or 10 deg; with stamps and without one, poses more than 1 m apart; without stamps,\n\
         % a wrong join shortly before); wrong joins: stretches the final trajectory keeps\n\
         % within 1 m over 3 m that ground truth keeps 2.5 m apart; silent joins: of those,\n\
         % the ones no accepted loop explains.\n",
    );
    let _ = writeln!(out, "\\begin{{tabular}}{{l{}}}", "r".repeat(n));
    out.push_str("\\toprule\nscenario");
    for (scenario, range) in &groups {
        let _ = write!(
            out,
            " & \\multicolumn{{{}}}{{c}}{{{}}}",
            range.len(),
            escape(scenario)
        );
    }
    out.push_str(" \\\\\n");
    if !groups.is_empty() {
        let rules: Vec<String> = groups
            .iter()
            .map(|(_, r)| format!("\\cmidrule(lr){{{}-{}}}", r.start + 2, r.end + 1))
            .collect();
        let _ = writeln!(out, "{}", rules.join(" "));
    }
    out.push_str("system");
    for column in &table.columns {
        let _ = write!(out, " & {}", escape(&column.run.plugin));
    }
    out.push_str(" \\\\\n\\midrule\n");
    for (r, row) in table.rows().iter().enumerate() {
        if r == super::table::ERROR_ROWS {
            // The real-time factor and the loops are not error statistics: set them apart.
            out.push_str("\\midrule\n");
        }
        out.push_str(&escape(row.label));
        for i in 0..n {
            let _ = write!(out, " & {}", row.text(i));
        }
        out.push_str(" \\\\\n");
    }
    out.push_str("\\bottomrule\n\\end{tabular}\n");

    let failures: Vec<String> = table
        .failures()
        .map(|(scenario, plugin, reason)| {
            format!(
                "{}/{}: {}",
                escape(scenario),
                escape(plugin),
                escape(reason)
            )
        })
        .collect();
    if !failures.is_empty() {
        let _ = writeln!(
            out,
            "\\par\\smallskip{{\\footnotesize Failed runs: {}.\\par}}",
            failures.join("; ")
        );
    }
    if let Some(note) = table.cut_note() {
        let _ = writeln!(
            out,
            "\\par\\smallskip{{\\footnotesize {}\\par}}",
            escape(&note)
        );
    }
    out
}
