//! The table as CSV: a header `statistic,<scenario>/<plugin>,…`, one row per statistic
//! (3 decimals, as the Markdown), `RTF` (1 decimal), `loops` and `false loops` (counts)
//! and a last `status` row (`ok` or `failed: <reason>`). Fields are quoted as RFC 4180 says; lines end with `\n`.

use super::table::Table;

/// `field` quoted if it contains a comma, quote or line break (quotes doubled).
fn field(text: &str) -> String {
    if text.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", text.replace('"', "\"\""))
    } else {
        text.to_owned()
    }
}

fn line(out: &mut String, fields: impl IntoIterator<Item = String>) {
    let fields: Vec<String> = fields.into_iter().map(|f| field(&f)).collect();
    out.push_str(&fields.join(","));
    out.push('\n');
}

/// The CSV of `table`.
pub(super) fn render(table: &Table) -> String {
    let mut out = String::new();
    line(
        &mut out,
        std::iter::once("statistic".to_owned()).chain(
            table
                .columns
                .iter()
                .map(|c| format!("{}/{}", c.run.scenario, c.run.plugin)),
        ),
    );
    for row in table.rows() {
        line(
            &mut out,
            std::iter::once(row.label.to_owned()).chain((0..row.cells.len()).map(|i| row.text(i))),
        );
    }
    line(
        &mut out,
        std::iter::once("status".to_owned()).chain(table.columns.iter().map(
            |c| match &c.failure {
                None => "ok".to_owned(),
                Some(reason) => format!("failed: {reason}"),
            },
        )),
    );
    out
}
