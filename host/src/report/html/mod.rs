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

mod bench;
mod sweep;

pub use bench::{bench_page, write_bench_report};
pub use sweep::{sweep_page, write_sweep_report};

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
figure.pair img{width:49%;margin-right:1%}
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
