//! `report.html` from the outside: written by real benches and sweeps (the paper test's,
//! the faulty-plugin bench, the results.mcap test's bench with loops, a sweep), it names every run
//! with the numbers of `table.json`, draws every accepted loop, and renders in a real
//! browser (Debian's Chromium, headless, through tests/browser/check_report.py) without a
//! console error, a broken image, an empty SVG or a request outside the page;
//! `vinebench report DIR` rebuilds it byte for byte.
//!
//! The browser check needs Chromium and `websocket-client`: scripts/test.sh installs both
//! (scripts/setup.sh) and sets `VINEBENCH_REQUIRE_BROWSER=1`, so there a missing browser
//! fails the test; elsewhere the browser part is skipped with a message.

use std::path::Path;
use std::process::Command;

use serde_json::Value;

use crate::common::{json, text, vinebench};

/// Whether the test command has installed the browser: then its absence is a failure.
fn browser_required() -> bool {
    std::env::var_os("VINEBENCH_REQUIRE_BROWSER").is_some_and(|v| v == "1")
}

/// Runs tests/browser/check_report.py on `report` (a full-page screenshot next to it, and
/// one per `(selector, file name)` of `sections`); returns its JSON, or `None` when no
/// browser is installed and none is required.
pub fn browser_check(report: &Path, sections: &[(&str, &str)]) -> Option<Value> {
    let chromium = Path::new("/usr/bin/chromium");
    if !chromium.exists() {
        assert!(
            !browser_required(),
            "VINEBENCH_REQUIRE_BROWSER=1 but {} is missing",
            chromium.display()
        );
        eprintln!("browser check skipped: no Chromium here (scripts/test.sh installs it)");
        return None;
    }
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/browser/check_report.py");
    let dir = report.parent().expect("a folder");
    let mut cmd = Command::new("python3");
    cmd.arg(&script)
        .arg(report)
        .arg("--screenshot")
        .arg(dir.join("report.png"));
    for (selector, file) in sections {
        cmd.arg("--section-screenshot")
            .arg(selector)
            .arg(dir.join(file));
    }
    let out = cmd
        .output()
        .expect("python3 on PATH (source scripts/setup.sh)");
    assert!(
        out.status.success(),
        "{} does not render cleanly in Chromium: {}",
        report.display(),
        text(&out.stderr)
    );
    let summary: Value = serde_json::from_slice(&out.stdout).expect("check_report.py prints JSON");
    for shot in summary["screenshots"].as_array().expect("screenshots") {
        let path = Path::new(shot.as_str().expect("a path"));
        let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        assert!(
            bytes.starts_with(b"\x89PNG") && bytes.len() > 10_000,
            "{}: not a real screenshot ({} bytes)",
            path.display(),
            bytes.len()
        );
    }
    Some(summary)
}

/// Checks a bench's report against its `table.json`: every scenario and system is named,
/// every ok run's RMSE appears as the table prints it, every failed run's reason is shown;
/// the page renders in a browser (with `min_images` images or more: maps and grids) and
/// `vinebench report` rebuilds the same bytes. Returns the page.
pub fn check_bench_report(out: &Path, min_images: u64) -> String {
    let path = out.join("report.html");
    let page = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let table = json(&out.join("table.json"));
    for (scenario, runs) in table.as_object().expect("scenarios") {
        assert!(
            page.contains(&format!("id=\"scenario-{scenario}\"")),
            "no section for {scenario}"
        );
        for (system, run) in runs.as_object().expect("systems") {
            assert!(
                page.contains(&format!("<th>{system}</th>")),
                "{system} is not in the table"
            );
            let status = run["status"].as_str().expect("status");
            if status == "ok" {
                let rmse = format!("<td>{:.3}</td>", run["rmse"].as_f64().expect("rmse"));
                assert!(
                    page.contains(&rmse),
                    "{scenario}/{system}: rmse {rmse} not in the page"
                );
                assert!(
                    page.contains(&format!("id=\"run-{scenario}-{system}\"")),
                    "{scenario}/{system}: no run section"
                );
            } else {
                let reason = status.trim_start_matches("failed: ");
                let shown = reason
                    .replace('&', "&amp;")
                    .replace('"', "&quot;")
                    .replace('\'', "&#39;");
                assert!(
                    page.contains(&shown),
                    "{scenario}/{system}: the failure {reason:?} is not shown"
                );
            }
        }
    }
    let before = std::fs::read(&path).expect("report");
    let o = vinebench(&["report", out.to_str().expect("utf-8")]);
    assert!(o.status.success(), "vinebench report: {}", text(&o.stderr));
    assert!(
        text(&o.stdout).contains(&format!("({} bytes)", before.len())),
        "vinebench report prints the page's size: {}",
        text(&o.stdout)
    );
    assert!(
        std::fs::read(&path).expect("report") == before,
        "vinebench report rebuilt a different page"
    );
    if let Some(summary) = browser_check(&path, &[("#table", "report-table.png")]) {
        assert!(
            summary["images"].as_u64().expect("images") >= min_images,
            "expected at least {min_images} images (maps, grids): {summary}"
        );
        let scenarios = table.as_object().expect("scenarios").len() as u64;
        assert!(
            summary["svgs"].as_u64().expect("svgs") >= scenarios,
            "expected a trajectory plot per scenario at least: {summary}"
        );
    }
    page
}

/// The report of a bench whose runs `labels` (on S1) closed loops: the S1 plot draws one
/// grey segment per accepted loop that ground truth confirms and one red per false one,
/// and each run lists its loops with their judgement; the page passes
/// [`check_bench_report`]. Called by the results.mcap test, whose bench closes loops.
pub fn check_bench_loops(out: &Path, labels: &[&str]) {
    let page = check_bench_report(out, 1);
    let (mut accepted, mut false_loops) = (0, 0);
    for label in labels {
        let metrics = json(&out.join("s1").join(label).join("metrics.json"));
        let (a, f) = (
            metrics["loops"]["accepted"].as_u64().expect("accepted"),
            metrics["loops"]["accepted_false"]
                .as_u64()
                .expect("accepted_false"),
        );
        assert!(a > 0, "{label} accepted no loop: nothing to draw");
        let run = &page[page
            .find(&format!("id=\"run-s1-{label}\""))
            .unwrap_or_else(|| panic!("{label}'s run"))..];
        // Up to the next run's section.
        let run = &run[..run[1..]
            .find("<details id=\"run-")
            .map_or(run.len(), |i| i + 1)];
        let judged = run.matches("<span class=\"good\">true</span>").count()
            + run.matches("<span class=\"bad\">false</span>").count();
        assert_eq!(
            judged as u64, a,
            "{label}: one listed loop per accepted loop"
        );
        (accepted, false_loops) = (accepted + a, false_loops + f);
    }
    // The S1 section's SVG: loops are segments in the loop colours, true 1 px grey, false
    // 2 px red (the legend's swatches are 3 px).
    let section = &page[page.find("id=\"scenario-s1\"").expect("s1 section")..];
    let section = &section[..section.find("</section>").expect("section end")];
    let segments = |colour: &str, width: u32| {
        section
            .matches(&format!("stroke=\"{colour}\" stroke-width=\"{width}\""))
            .count() as u64
    };
    assert_eq!(
        (segments("#6E6E6E", 1), segments("#E6001E", 2)),
        (accepted - false_loops, false_loops),
        "grey and red segments against {accepted} accepted, {false_loops} false loops"
    );
    eprintln!(
        "report: {} bytes, {accepted} loops ({false_loops} false)",
        page.len()
    );
}

/// Bad input to `vinebench report`: one line naming the folder, non-zero, nothing written.
#[test]
fn report_refuses_what_is_not_a_results_folder() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let missing = tmp.path().join("nope");
    let o = vinebench(&["report", missing.to_str().expect("utf-8")]);
    let err = text(&o.stderr);
    assert!(
        !o.status.success() && err.contains("nope") && err.trim().lines().count() == 1,
        "{err}"
    );
    let empty = tmp.path().join("empty");
    std::fs::create_dir(&empty).expect("dir");
    let o = vinebench(&["report", empty.to_str().expect("utf-8")]);
    let err = text(&o.stderr);
    assert!(
        !o.status.success() && err.contains("table.json") && err.trim().lines().count() == 1,
        "{err}"
    );
    assert!(
        !empty.join("report.html").exists(),
        "no page for an empty folder"
    );
}
