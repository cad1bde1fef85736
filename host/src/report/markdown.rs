//! The table as GitHub-flavoured Markdown, padded so it also reads in a terminal.
//!
//! GFM has one header row, so the paper's two-level header is emulated: the header row
//! names each scenario above its first system, and the first body row (`system`) names
//! the systems. Failed runs are listed with their reasons below the table, and routes cut
//! short (`--max-time`) are said to be so.

use std::fmt::Write as _;

use super::table::Table;

pub(super) const CAPTION: &str = "APE translation after alignment in metres; \
    RTF: the system's real-time factor (simulated seconds per second spent in its calls, \
    finish included; the simulator's time is not counted); \
    loops: loop closures accepted; false loops: of those, the ones ground truth shows \
    false (a measured relative pose off by more than 0.5 m or 10°; without one, poses more \
    than 1 m apart).";

pub(super) const PAPER_CAPTION: &str = "paper max .. paper std: the figures the paper \
    published for that system and scenario (Hroob et al. 2021, Table 2; `paper.csv`), not ours.";

/// `text` safe inside a table cell: `|` escaped.
fn cell(text: &str) -> String {
    text.replace('|', "\\|")
}

/// The Markdown of `table`, ending with a newline.
pub(super) fn render(table: &Table) -> String {
    let n = table.columns.len();
    // Every line as [label, cell per column]; the first is the header.
    let mut lines: Vec<Vec<String>> = Vec::new();
    let mut header = vec![String::new(); n + 1];
    header[0] = "scenario".to_owned();
    for (scenario, range) in table.groups() {
        header[range.start + 1] = cell(scenario);
    }
    lines.push(header);
    lines.push(
        std::iter::once("system".to_owned())
            .chain(table.columns.iter().map(|c| cell(&c.run.plugin)))
            .collect(),
    );
    for row in table.rows() {
        lines.push(
            std::iter::once(row.label.to_owned())
                .chain((0..n).map(|i| row.text(i)))
                .collect(),
        );
    }
    let widths: Vec<usize> = (0..=n)
        .map(|j| {
            lines
                .iter()
                .map(|l| l[j].chars().count())
                .fold(3, usize::max)
        })
        .collect();

    let mut out = String::new();
    for (i, line) in lines.iter().enumerate() {
        out.push('|');
        for (j, (text, &w)) in line.iter().zip(&widths).enumerate() {
            // Labels left-aligned, values right-aligned.
            let _ = if j == 0 {
                write!(out, " {text:<w$} |")
            } else {
                write!(out, " {text:>w$} |")
            };
        }
        out.push('\n');
        if i == 0 {
            let _ = write!(out, "|{}|", "-".repeat(widths[0] + 2));
            for &w in &widths[1..] {
                let _ = write!(out, "{}:|", "-".repeat(w + 1));
            }
            out.push('\n');
        }
    }
    let _ = write!(out, "\n{CAPTION}\n");
    if table.reference.is_some() {
        let _ = write!(out, "\n{PAPER_CAPTION}\n");
    }
    if let Some(note) = table.cut_note() {
        let _ = write!(out, "\n{note}\n");
    }

    let unjudged: Vec<_> = table.unjudged_loops().collect();
    if !unjudged.is_empty() {
        out.push_str("\nAccepted loops without stamps, not judged:\n\n");
        for (scenario, plugin, n) in unjudged {
            let _ = writeln!(out, "- {scenario} / {plugin}: {n}");
        }
    }

    let failures: Vec<_> = table.failures().collect();
    if !failures.is_empty() {
        out.push_str("\nFailed runs:\n\n");
        for (scenario, plugin, reason) in failures {
            let _ = writeln!(out, "- {scenario} / {plugin}: {reason}");
        }
    }
    out
}
