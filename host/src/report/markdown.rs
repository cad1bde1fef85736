//! The table as GitHub-flavoured Markdown, padded so it also reads in a terminal.
//!
//! GFM has one header row, so the paper's two-level header is emulated: the header row
//! names each scenario above its first system, and the first body row (`system`) names
//! the systems. Failed runs are listed with their reasons below the table, and routes cut
//! short (`--max-time`) are said to be so.

use std::fmt::Write as _;

use super::table::Table;

pub(super) const CAPTION: &str = "APE translation after alignment in metres (max .. min); \
    scale: of a Sim(3) alignment (1 for a metric system); drift %: translation drift over \
    5-20 m segments, metres per 100 m; \
    RTF: the system's real-time factor (simulated seconds per second spent in its calls, \
    finish included; the simulator's time is not counted); \
    loops: loop closures accepted; false loops: of those, the ones ground truth shows \
    false (a measured relative pose off by more than 0.5 m or 10°; with stamps and without \
    one, poses more than 1 m apart; without stamps, a wrong join of the final map shortly \
    before); wrong joins: stretches the final trajectory keeps within 1 m over 3 m or more \
    that ground truth keeps more than 2.5 m apart, whatever the system reported; silent \
    joins: of those, the ones no accepted loop explains.";

pub(super) const PAPER_CAPTION: &str = "paper max .. paper std: the figures the paper \
    published for that system and scenario (Hroob et al. 2021, Table 2; `paper.csv`), not ours.";

pub(super) const LOCALIZATION_CAPTION: &str = "localised .. wrong lane s: a localisation \
    run's judgement (vinebench localize): localised, 1 when the first correct pose came \
    within 10 m of travel; to localise s, time to it; localised %, the time the system said \
    it was localised; ATE in map, RMSE of those poses in the map's frame without \
    re-alignment (the mapping run's alignment carried over); false s and false vs map s, \
    time said localised more than 0.5 m or 10 deg off the truth, and off the mapping run's \
    own estimate at the same place; wrong lane s, time said localised between other rows \
    than the truth. The APE rows above are of the final trajectory, aligned as any run.";

/// `text` safe inside a table cell: `|` escaped.
fn cell(text: &str) -> String {
    text.replace('|', "\\|")
}

/// The Markdown of `table`, ending with a newline: one table of every column under a
/// two-level header, then the notes.
pub(super) fn render(table: &Table) -> String {
    let n = table.columns.len();
    let mut header = vec![String::new(); n + 1];
    header[0] = "scenario".to_owned();
    for (scenario, range) in table.groups() {
        header[range.start + 1] = cell(scenario);
    }
    let systems = std::iter::once("system".to_owned())
        .chain(table.columns.iter().map(|c| cell(&c.run.plugin)))
        .collect();
    let mut out = grid(table, 0..n, vec![header, systems]);
    out.push_str(&notes(table));
    out
}

/// The same table for a terminal: one block per scenario (its name above its systems), so
/// that a bench of many systems stays narrow, then the notes.
pub(super) fn render_blocks(table: &Table) -> String {
    let mut out = String::new();
    for (k, (scenario, range)) in table.groups().into_iter().enumerate() {
        if k > 0 {
            out.push('\n');
        }
        let header = std::iter::once(cell(scenario))
            .chain(
                table.columns[range.clone()]
                    .iter()
                    .map(|c| cell(&c.run.plugin)),
            )
            .collect();
        out.push_str(&grid(table, range, vec![header]));
    }
    out.push_str(&notes(table));
    out
}

/// Columns `cols` of the table under the `head` lines (label first, then one per column),
/// padded; a rule under the first.
fn grid(table: &Table, cols: std::ops::Range<usize>, head: Vec<Vec<String>>) -> String {
    // Every line as [label, cell per column]; the first is the header.
    let mut lines = head;
    for row in table.rows() {
        lines.push(
            std::iter::once(row.label.to_owned())
                .chain(cols.clone().map(|i| row.text(i)))
                .collect(),
        );
    }
    let widths: Vec<usize> = (0..=cols.len())
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
    out
}

/// What follows the table: the captions, a cut route, unjudged loops, failed runs.
fn notes(table: &Table) -> String {
    let mut out = String::new();
    let _ = write!(out, "\n{CAPTION}\n");
    if table.reference.is_some() {
        let _ = write!(out, "\n{PAPER_CAPTION}\n");
    }
    if table.columns.iter().any(|c| c.run.localization.is_some()) {
        let _ = write!(out, "\n{LOCALIZATION_CAPTION}\n");
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
