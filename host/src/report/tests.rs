//! Reports of a hand-made 2 scenarios × 2 plugins benchmark with one failed run.

use std::path::Path;

use super::*;

fn stats(base: f64) -> eval::Statistics {
    eval::Statistics {
        pairs: 100,
        rmse: base + 0.4,
        mean: base + 0.2,
        median: base + 0.3,
        std: base + 0.05,
        min: base,
        max: base + 0.9,
        sse: 1.0,
    }
}

/// An ok run; `10 × base` loops accepted, `base` of them false.
fn ok(scenario: &str, plugin: &str, base: f64, rtf: f64, dy: f64) -> RunRecord {
    RunRecord {
        scenario: scenario.to_owned(),
        plugin: plugin.to_owned(),
        status: RunStatus::Ok,
        ape: Some(stats(base)),
        realtime_factor: Some(rtf),
        loops: Some(eval::LoopCounts {
            accepted: 10 * base as usize,
            accepted_false: base as usize,
            rejected: 7,
            unjudged: 0,
        }),
        joins: Some(crate::results::JoinCounts {
            wrong_joins: base as usize + 1,
            silent: base as usize,
            ..Default::default()
        }),
        sim3_scale: Some(1.0 + base / 100.0),
        drift_percent: Some(base / 2.0),
        estimate_xy: (0..=50).map(|i| (f64::from(i) * 0.5, dy)).collect(),
        max_time_s: None,
        localization: None,
    }
}

fn names(names: &[&str]) -> Vec<String> {
    names.iter().map(|s| (*s).to_owned()).collect()
}

/// s0: wheel-odometry ok (1.0…), lio_sam ok (2.0…, 4 of its loops unjudged); s1:
/// wheel-odometry ok (3.0…), lio_sam failed with a reason containing a comma and a quote.
fn bench() -> (Vec<String>, Vec<String>, Vec<RunRecord>, Vec<ScenarioTruth>) {
    let mut unjudged = ok("s0", "lio_sam", 2.0, 5.06, -0.8);
    if let Some(loops) = &mut unjudged.loops {
        loops.unjudged = 4;
    }
    let runs = vec![
        ok("s0", "wheel-odometry", 1.0, 12.34, 0.8),
        unjudged,
        ok("s1", "wheel-odometry", 3.0, 7.26, 1.0),
        RunRecord {
            scenario: "s1".into(),
            plugin: "lio_sam".into(),
            status: RunStatus::Failed("timed out after 600 s, \"no map\"".into()),
            ape: None,
            realtime_factor: None,
            loops: None,
            joins: None,
            sim3_scale: None,
            drift_percent: None,
            estimate_xy: Vec::new(),
            max_time_s: None,
            localization: None,
        },
    ];
    let truths = ["s0", "s1"]
        .iter()
        .map(|s| ScenarioTruth {
            scenario: (*s).to_owned(),
            groundtruth_xy: (0..=50).map(|i| (f64::from(i) * 0.5, 0.0)).collect(),
        })
        .collect();
    (
        names(&["s0", "s1"]),
        names(&["wheel-odometry", "lio_sam"]),
        runs,
        truths,
    )
}

fn write(dir: &Path) -> String {
    let (scenarios, plugins, runs, truths) = bench();
    write_reports(dir, &scenarios, &plugins, &runs, &truths, None)
        .expect("expected reports written")
}

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("expected {}: {e}", path.display()))
}

/// The cells of a Markdown table line, trimmed.
fn md_cells(line: &str) -> Vec<&str> {
    let inner = line.trim().trim_start_matches('|').trim_end_matches('|');
    inner.split('|').map(str::trim).collect()
}

#[test]
fn markdown_puts_numbers_under_their_scenario_and_system() {
    let dir = tempfile::tempdir().unwrap();
    let md = write(dir.path());
    assert_eq!(
        md,
        read(&dir.path().join("table.md")),
        "expected the returned Markdown to be table.md"
    );
    let lines: Vec<&str> = md.lines().collect();
    let row = |label: &str| {
        lines
            .iter()
            .map(|l| md_cells(l))
            .find(|c| c[0] == label)
            .unwrap_or_else(|| panic!("expected a row {label:?} in\n{md}"))
    };
    assert_eq!(
        md_cells(lines[0]),
        ["scenario", "s0", "", "s1", ""],
        "expected scenario headers over their first system in\n{md}"
    );
    assert!(
        md_cells(lines[1])
            .iter()
            .skip(1)
            .all(|c| c.ends_with(':') && c.starts_with('-')),
        "expected a right-aligned GFM delimiter row, got {:?}",
        lines[1]
    );
    assert_eq!(
        row("system"),
        [
            "system",
            "wheel-odometry",
            "lio_sam",
            "wheel-odometry",
            "lio_sam"
        ],
        "expected the systems row in\n{md}"
    );
    assert_eq!(
        row("max"),
        ["max", "1.900", "2.900", "3.900", "failed"],
        "expected max in\n{md}"
    );
    assert_eq!(
        row("mean"),
        ["mean", "1.200", "2.200", "3.200", "failed"],
        "expected mean in\n{md}"
    );
    assert_eq!(
        row("median"),
        ["median", "1.300", "2.300", "3.300", "failed"],
        "expected median in\n{md}"
    );
    assert_eq!(
        row("rmse"),
        ["rmse", "1.400", "2.400", "3.400", "failed"],
        "expected rmse in\n{md}"
    );
    assert_eq!(
        row("std"),
        ["std", "1.050", "2.050", "3.050", "failed"],
        "expected std in\n{md}"
    );
    assert_eq!(
        row("RTF"),
        ["RTF", "12.3", "5.1", "7.3", "failed"],
        "expected RTF in\n{md}"
    );
    assert_eq!(
        row("loops"),
        ["loops", "10", "20", "30", "failed"],
        "expected the accepted loops in\n{md}"
    );
    assert_eq!(
        row("false loops"),
        ["false loops", "1", "2", "3", "failed"],
        "expected the false loops in\n{md}"
    );
    let widths: Vec<usize> = lines[..11].iter().map(|l| l.chars().count()).collect();
    assert!(
        widths.iter().all(|&w| w == widths[0]),
        "expected padded table lines of one width for the terminal, got {widths:?} in\n{md}"
    );
    assert!(
        md.contains("Failed runs:\n\n- s1 / lio_sam: timed out after 600 s, \"no map\"\n"),
        "expected the failure reason listed below the table in\n{md}"
    );
    assert!(
        md.contains("Accepted loops without stamps, not judged:\n\n- s0 / lio_sam: 4\n"),
        "expected the unjudged loops listed below the table in\n{md}"
    );
}

#[test]
fn csv_parses_back_to_the_numbers() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path());
    let csv = read(&dir.path().join("table.csv"));
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(
        lines[0], "statistic,s0/wheel-odometry,s0/lio_sam,s1/wheel-odometry,s1/lio_sam",
        "expected the CSV header"
    );
    let labels: Vec<&str> = lines.iter().map(|l| l.split(',').next().unwrap()).collect();
    assert_eq!(
        labels,
        [
            "statistic",
            "max",
            "mean",
            "median",
            "rmse",
            "std",
            "min",
            "scale",
            "drift %",
            "RTF",
            "loops",
            "false loops",
            "wrong joins",
            "silent joins",
            "status"
        ],
        "expected one row per statistic, scale, drift, RTF, loops, joins and status in\n{csv}"
    );
    let expected = [
        [1.9, 2.9, 3.9],
        [1.2, 2.2, 3.2],
        [1.3, 2.3, 3.3],
        [1.4, 2.4, 3.4],
        [1.05, 2.05, 3.05],
        [1.0, 2.0, 3.0],
        [1.01, 1.02, 1.03],
        [0.5, 1.0, 1.5],
        [12.3, 5.1, 7.3],
        [10.0, 20.0, 30.0],
        [1.0, 2.0, 3.0],
        [2.0, 3.0, 4.0],
        [1.0, 2.0, 3.0],
    ];
    assert_eq!(lines.len(), expected.len() + 2, "{csv}");
    for (line, want) in lines[1..=expected.len()].iter().zip(expected) {
        let fields: Vec<&str> = line.split(',').collect();
        let values: Vec<f64> = fields[1..4]
            .iter()
            .map(|f| {
                f.parse()
                    .unwrap_or_else(|e| panic!("expected a number, got {f:?}: {e}"))
            })
            .collect();
        assert_eq!(values, want, "expected the ok runs' values in {line:?}");
        assert_eq!(
            fields[4], "failed",
            "expected the failed run's cell in {line:?}"
        );
    }
    assert_eq!(
        lines[14], "status,ok,ok,ok,\"failed: timed out after 600 s, \"\"no map\"\"\"",
        "expected the status row with the reason quoted as RFC 4180 says"
    );
}

#[test]
fn latex_has_multicolumn_headers_and_escaped_labels() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path());
    let tex = read(&dir.path().join("table.tex"));
    for expected in [
        "\\begin{tabular}{lrrrr}",
        "\\toprule",
        "scenario & \\multicolumn{2}{c}{s0} & \\multicolumn{2}{c}{s1} \\\\",
        "\\cmidrule(lr){2-3} \\cmidrule(lr){4-5}",
        "system & wheel-odometry & lio\\_sam & wheel-odometry & lio\\_sam \\\\",
        "\\midrule",
        "rmse & 1.400 & 2.400 & 3.400 & failed \\\\",
        "\\midrule\nscale & 1.010 & 1.020 & 1.030 & failed \\\\\ndrift \\% & 0.50 & 1.00 & 1.50 & failed \\\\\nRTF & 12.3 & 5.1 & 7.3 & failed \\\\\nloops & 10 & 20 & 30 & failed \\\\\nfalse loops & 1 & 2 & 3 & failed \\\\\nwrong joins & 2 & 3 & 4 & failed \\\\\nsilent joins & 1 & 2 & 3 & failed \\\\\n\\bottomrule",
        "\\bottomrule",
        "\\end{tabular}",
        "Failed runs: s1/lio\\_sam: timed out after 600 s, \"no map\".",
    ] {
        assert!(tex.contains(expected), "expected {expected:?} in\n{tex}");
    }
    assert_eq!(
        latex::escape("a_b&c%d#e"),
        "a\\_b\\&c\\%d\\#e",
        "expected _ & % # escaped"
    );
}

#[test]
fn json_has_the_design_shape() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path());
    let text = read(&dir.path().join("table.json"));
    let json: serde_json::Value = serde_json::from_str(&text).expect("expected valid JSON");
    let expected = serde_json::json!({
        "s0": {
            "wheel-odometry": {"status": "ok", "rmse": 1.4, "mean": 1.2, "median": 1.3,
                "max": 1.9, "min": 1.0, "std": 1.05, "realtime_factor": 12.34,
                "loops_accepted": 10, "loops_false": 1, "wrong_joins": 2, "silent_joins": 1,
                "sim3_scale": 1.01, "drift_percent": 0.5},
            "lio_sam": {"status": "ok", "rmse": 2.4, "mean": 2.2, "median": 2.3,
                "max": 2.9, "min": 2.0, "std": 2.05, "realtime_factor": 5.06,
                "loops_accepted": 20, "loops_false": 2, "loops_unjudged": 4,
                "wrong_joins": 3, "silent_joins": 2, "sim3_scale": 1.02, "drift_percent": 1.0},
        },
        "s1": {
            "wheel-odometry": {"status": "ok", "rmse": 3.4, "mean": 3.2, "median": 3.3,
                "max": 3.9, "min": 3.0, "std": 3.05, "realtime_factor": 7.26,
                "loops_accepted": 30, "loops_false": 3, "wrong_joins": 4, "silent_joins": 3,
                "sim3_scale": 1.03, "drift_percent": 1.5},
            "lio_sam": {"status": "failed: timed out after 600 s, \"no map\""},
        },
    });
    assert_eq!(
        json, expected,
        "expected the DESIGN.md shape with full precision"
    );
    let s0 = text.find("\"s0\"").expect("expected s0");
    let s1 = text.find("\"s1\"").expect("expected s1");
    let wheel = text
        .find("\"wheel-odometry\"")
        .expect("expected wheel-odometry");
    let lio = text.find("\"lio_sam\"").expect("expected lio_sam");
    assert!(
        s0 < s1 && wheel < lio,
        "expected the given scenario and plugin order in\n{text}"
    );
}

/// The contents of an SVG's `<text>` elements.
fn svg_texts(svg: &str) -> Vec<&str> {
    svg.split("</text>")
        .filter_map(|chunk| chunk.rfind("<text").map(|i| &chunk[i..]))
        .filter_map(|t| t.split_once('>').map(|(_, body)| body.trim()))
        .collect()
}

fn png_pixels(path: &Path) -> (u32, u32, Vec<u8>) {
    let bytes = std::fs::read(path).unwrap();
    assert!(
        bytes.starts_with(b"\x89PNG\r\n\x1a\n"),
        "expected the PNG signature at the start of {}",
        path.display()
    );
    let decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    let mut reader = decoder.read_info().expect("expected a readable PNG");
    let mut buf = vec![0; reader.output_buffer_size().expect("expected a buffer size")];
    let info = reader.next_frame(&mut buf).expect("expected a frame");
    assert_eq!(info.color_type, png::ColorType::Rgb, "expected an RGB PNG");
    buf.truncate(info.buffer_size());
    (info.width, info.height, buf)
}

#[test]
fn plots_show_ground_truth_and_estimates() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path());
    for scenario in ["s0", "s1"] {
        let png = dir.path().join("plots").join(format!("{scenario}.png"));
        let svg = read(&dir.path().join("plots").join(format!("{scenario}.svg")));
        let (width, height, pixels) = png_pixels(&png);
        assert_eq!(width, 1000, "expected a 1000 px wide plot");
        // The ground truth runs along y = 0, the middle of the 300 px plot area; the
        // legend band lies below row 300.
        let black_in_plot = pixels[..(300 * width * 3) as usize]
            .chunks_exact(3)
            .filter(|p| *p == [0, 0, 0])
            .count();
        assert!(
            black_in_plot > 1000,
            "expected the black ground truth in the plot area of {scenario}, found {black_in_plot} black pixels"
        );
        let blue = pixels
            .chunks_exact(3)
            .filter(|p| *p == [0, 114, 178])
            .count();
        assert!(
            blue > 1000,
            "expected wheel-odometry in blue in {scenario}, found {blue} pixels"
        );
        assert!(
            height > 300,
            "expected a legend band below the plot, height {height}"
        );
        let texts = svg_texts(&svg);
        for text in [
            "wheel-odometry",
            "ground truth",
            "x (m)",
            "y (m)",
            &format!("{scenario}: aligned estimates over ground truth"),
        ] {
            assert!(
                texts.contains(&text),
                "expected {text:?} among the SVG's texts {texts:?}"
            );
        }
        assert!(
            svg.starts_with("<svg") && svg.contains("#0072B2"),
            "expected wheel-odometry in blue in\n{svg}"
        );
        // The PNG draws the same text: the legend band below the plot has dark glyph
        // pixels (the SVG's legend labels, rasterised).
        let legend_band = &pixels[((height - 30) * width * 3) as usize..];
        let dark = legend_band
            .chunks_exact(3)
            .filter(|p| p.iter().all(|&v| v < 80))
            .count();
        assert!(
            dark > 100,
            "expected legend text in the PNG of {scenario}, found {dark} dark pixels"
        );
    }
    let s1 = read(&dir.path().join("plots/s1.svg"));
    assert!(
        svg_texts(&s1).contains(&"lio_sam: failed (timed out after 600 s, &quot;no map&quot;)"),
        "expected the failed system in the s1 legend in\n{s1}"
    );
    let s1_png = png_pixels(&dir.path().join("plots/s1.png")).2;
    assert!(
        !s1_png.chunks_exact(3).any(|p| p == [213, 94, 0]),
        "expected no vermillion (lio_sam) line in s1, where it failed"
    );
}

#[test]
fn writing_twice_gives_identical_files() {
    let (a, b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    write(a.path());
    write(b.path());
    for file in [
        "table.md",
        "table.csv",
        "table.tex",
        "table.json",
        "plots/s0.png",
        "plots/s0.svg",
        "plots/s1.png",
        "plots/s1.svg",
    ] {
        let (x, y) = (
            std::fs::read(a.path().join(file)).unwrap(),
            std::fs::read(b.path().join(file)).unwrap(),
        );
        assert!(x == y, "expected {file} byte-identical across two writes");
    }
}

#[test]
fn duplicate_runs_are_an_error_and_extra_names_get_columns() {
    let (scenarios, plugins, mut runs, truths) = bench();
    let dir = tempfile::tempdir().unwrap();
    runs.push(ok("s2", "kiss-icp", 0.0, 1.0, 0.0));
    let md = write_reports(dir.path(), &scenarios, &plugins, &runs, &truths, None).unwrap();
    assert!(
        md.lines().next().unwrap().contains("s2") && md.contains("kiss-icp"),
        "expected a run of an unlisted scenario and plugin to get a column in\n{md}"
    );
    assert!(
        dir.path().join("plots/s2.png").exists(),
        "expected a plot of the unlisted scenario"
    );
    runs.push(ok("s0", "lio_sam", 0.0, 1.0, 0.0));
    let err = write_reports(dir.path(), &scenarios, &plugins, &runs, &truths, None)
        .expect_err("expected two runs of one pair to be an error");
    assert!(
        err.to_string()
            .contains("two runs of plugin \"lio_sam\" on scenario \"s0\""),
        "expected the error to name the pair, got {err}"
    );
}

/// A table of cut routes says so in the Markdown and the LaTeX, and every run in
/// table.json has the limit; a table of whole routes says nothing of it.
#[test]
fn cut_routes_are_said_to_be_cut() {
    let (scenarios, plugins, mut runs, truths) = bench();
    let whole = tempfile::tempdir().unwrap();
    let md = write_reports(whole.path(), &scenarios, &plugins, &runs, &truths, None).unwrap();
    assert!(
        !md.contains("max_time_s")
            && !read(&whole.path().join("table.json")).contains("max_time_s"),
        "expected no route limit in the reports of whole routes:\n{md}"
    );
    for run in &mut runs {
        run.max_time_s = Some(20.0);
    }
    let cut = tempfile::tempdir().unwrap();
    let md = write_reports(cut.path(), &scenarios, &plugins, &runs, &truths, None).unwrap();
    assert!(
        md.contains("Routes cut at 20 s of simulated time (max_time_s)")
            && md.contains("not the paper's table"),
        "expected the Markdown to say the routes were cut:\n{md}"
    );
    let tex = read(&cut.path().join("table.tex"));
    assert!(
        tex.contains("Routes cut at 20 s of simulated time (max\\_time\\_s)"),
        "expected the LaTeX to say the routes were cut:\n{tex}"
    );
    let json: serde_json::Value =
        serde_json::from_str(&read(&cut.path().join("table.json"))).unwrap();
    for (scenario, plugin) in [
        ("s0", "wheel-odometry"),
        ("s0", "lio_sam"),
        ("s1", "lio_sam"),
    ] {
        assert_eq!(
            json[scenario][plugin]["max_time_s"], 20.0,
            "expected {scenario}/{plugin} to carry the limit: {json}"
        );
    }
}

#[test]
fn loops_are_segments_grey_when_true_and_red_when_false() {
    use super::plot::{LoopSegment, Track, scenario_chart};
    let truth: Vec<(f64, f64)> = (0..50).map(|i| (f64::from(i) * 0.2, 0.0)).collect();
    let loops = [
        LoopSegment {
            from: (1.0, 0.0),
            to: (5.0, 0.0),
            true_loop: true,
            wrong_join: false,
        },
        LoopSegment {
            from: (2.0, 0.0),
            to: (8.0, 1.0),
            true_loop: false,
            wrong_join: false,
        },
        LoopSegment {
            from: (3.0, 0.0),
            to: (6.0, 0.0),
            true_loop: true,
            wrong_join: false,
        },
    ];
    let tracks = [
        Track {
            plugin: "a",
            plugin_index: 0,
            outcome: Ok((&truth, &loops)),
        },
        Track {
            plugin: "b",
            plugin_index: 1,
            outcome: Err("crashed"),
        },
    ];
    let svg = scenario_chart("s9", &truth, &tracks).to_svg(800).unwrap();
    let segments = |colour: &str, width: u32| {
        svg.matches(&format!("stroke=\"{colour}\" stroke-width=\"{width}\""))
            .count()
    };
    assert_eq!((segments("#6E6E6E", 1), segments("#E6001E", 2)), (2, 1));
    let texts = svg_texts(&svg);
    for label in [
        "true loop closures (2)",
        "false loop closures (1)",
        "b: failed (crashed)",
    ] {
        assert!(texts.contains(&label), "{label:?} not in {texts:?}");
    }
}

/// With the paper's table, rows `paper max` .. `paper std` carry its figures under the
/// columns whose (scenario, system) it has, blank under the others, and a line says whose.
#[test]
fn the_papers_figures_are_rows_beside_ours() {
    let (scenarios, plugins, runs, truths) = bench();
    let reference = reference::Reference::parse(
        "# test\nscenario,system,max,mean,median,rmse,std\ns0,lio_sam,1.65,1.00,1.11,1.13,0.53\n",
        "t.csv",
    )
    .expect("parses");
    let dir = tempfile::tempdir().unwrap();
    let md = write_reports(
        dir.path(),
        &scenarios,
        &plugins,
        &runs,
        &truths,
        Some(&reference),
    )
    .unwrap();
    let line = |label: &str| {
        md.lines()
            .find(|l| md_cells(l).first() == Some(&label))
            .unwrap_or_else(|| panic!("a {label} row in\n{md}"))
            .to_owned()
    };
    // Columns: s0 wheel-odometry, s0 lio_sam, s1 wheel-odometry, s1 lio_sam.
    assert_eq!(
        md_cells(&line("paper rmse")),
        ["paper rmse", "", "1.13", "", ""]
    );
    assert_eq!(
        md_cells(&line("paper max")),
        ["paper max", "", "1.65", "", ""]
    );
    assert_eq!(
        md_cells(&line("paper std")),
        ["paper std", "", "0.53", "", ""]
    );
    assert!(md.contains("Hroob et al. 2021, Table 2"), "{md}");
    let without = tempfile::tempdir().unwrap();
    let md = write_reports(without.path(), &scenarios, &plugins, &runs, &truths, None).unwrap();
    assert!(!md.contains("paper"), "no reference, no paper rows:\n{md}");
}
