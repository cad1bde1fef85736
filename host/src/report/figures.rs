//! The report's per-system and per-run figures: the map from above (the paper's Fig. 4),
//! the occupancy grid, and the translation error against time.

use std::path::Path;

use anyhow::Context as _;
use eval::plot::{Chart, ColorBar, Mark, Rgb, Swatch, viridis};

use super::load::RunDetail;

/// Points drawn of a map at most: a top view at report size shows no more.
const MAX_MAP_POINTS: usize = 400_000;
/// Points of a line in an inline SVG at most (the page stays light).
pub(super) const MAX_LINE_POINTS: usize = 1500;
const TRAJECTORY: Rgb = [220, 30, 30];
/// The map is drawn this far around the trajectory's bounding box, metres.
const MAP_MARGIN_M: f64 = 6.0;

/// Every `k`-th point (and the last) so that at most `max` remain.
pub(super) fn decimate<T: Copy>(points: &[T], max: usize) -> Vec<T> {
    if points.len() <= max {
        return points.to_vec();
    }
    let step = points.len().div_ceil(max.max(2) - 1);
    let mut out: Vec<T> = points.iter().step_by(step).copied().collect();
    if (points.len() - 1) % step != 0 {
        out.extend(points.last().copied());
    }
    out
}

/// The map of `map.ply` from above, points coloured by height (viridis between the 2nd
/// and 98th percentile, so a few stray points do not wash the colours out), the system's
/// own trajectory (its map frame) over it; `None` without a map.
pub(super) fn map_chart(
    title: &str,
    run_dir: &Path,
    detail: &RunDetail,
) -> anyhow::Result<Option<Chart>> {
    let path = run_dir.join(crate::results::files::MAP);
    if !path.exists() {
        return Ok(None);
    }
    let points = crate::results::read_ply(&path)?;
    // The map around the trajectory: a lidar's far returns (ground rings tens of metres
    // out) would shrink the vineyard to a corner.
    let (mut lo_x, mut hi_x, mut lo_y, mut hi_y) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for &(x, y) in &detail.estimate_raw_xy {
        (lo_x, hi_x, lo_y, hi_y) = (lo_x.min(x), hi_x.max(x), lo_y.min(y), hi_y.max(y));
    }
    let near = |p: &[f32; 3]| {
        let (x, y) = (f64::from(p[0]), f64::from(p[1]));
        !lo_x.is_finite()
            || (x >= lo_x - MAP_MARGIN_M
                && x <= hi_x + MAP_MARGIN_M
                && y >= lo_y - MAP_MARGIN_M
                && y <= hi_y + MAP_MARGIN_M)
    };
    let total = points.len();
    let points: Vec<[f32; 3]> = points.into_iter().filter(near).collect();
    let points = decimate(&points, MAX_MAP_POINTS);
    if points.is_empty() {
        return Ok(None);
    }
    let mut z: Vec<f32> = points
        .iter()
        .map(|p| p[2])
        .filter(|v| v.is_finite())
        .collect();
    z.sort_by(f32::total_cmp);
    let pick = |q: f64| f64::from(z[((z.len() - 1) as f64 * q).round() as usize]);
    let (lo, hi) = (pick(0.02), pick(0.98));
    let mut chart = Chart::top_view(title);
    chart.marks.push(Mark::Pixels {
        points: points
            .iter()
            .map(|p| {
                let t = if hi > lo {
                    (f64::from(p[2]) - lo) / (hi - lo)
                } else {
                    0.5
                };
                ((f64::from(p[0]), f64::from(p[1])), viridis(t))
            })
            .collect(),
    });
    chart.marks.push(Mark::Line {
        points: decimate(&detail.estimate_raw_xy, 20 * MAX_LINE_POINTS),
        color: TRAJECTORY,
        width_px: 2,
    });
    chart.legend.push((
        Swatch::Line {
            color: TRAJECTORY,
            width_px: 2,
        },
        "estimated trajectory (map frame)".into(),
    ));
    chart.legend.push((
        Swatch::Box(viridis(0.6)),
        format!(
            "{} of {total} map points (within {MAP_MARGIN_M} m of the trajectory)",
            points.len()
        ),
    ));
    chart.color_bar = Some(ColorBar {
        label: "height z (m)".into(),
        min: lo,
        max: hi,
    });
    Ok(Some(chart))
}

/// `grid.pgm` with `grid.yaml` (map_server's format) from above in metres, occupied black,
/// free white, unknown grey, the system's trajectory over it; `None` without a grid.
pub(super) fn grid_chart(
    title: &str,
    run_dir: &Path,
    detail: &RunDetail,
) -> anyhow::Result<Option<Chart>> {
    let (pgm, yaml) = (
        run_dir.join(crate::results::files::GRID),
        run_dir.join(crate::results::files::GRID_YAML),
    );
    if !pgm.exists() {
        return Ok(None);
    }
    let (width, height, cells) = read_pgm(&pgm)?;
    let (resolution, origin) = read_grid_yaml(&yaml)?;
    let mut rects = Vec::with_capacity(cells.len());
    for (k, &v) in cells.iter().enumerate() {
        // PGM rows run from the top: row 0 is the grid's last (largest y).
        let (col, row) = (k % width, height - 1 - k / width);
        let x = origin.0 + col as f64 * resolution;
        let y = origin.1 + row as f64 * resolution;
        rects.push(([(x, y), (x + resolution, y + resolution)], [v, v, v]));
    }
    let mut chart = Chart::top_view(title);
    chart.marks.push(Mark::Rects { rects });
    chart.marks.push(Mark::Line {
        points: decimate(&detail.estimate_raw_xy, 20 * MAX_LINE_POINTS),
        color: TRAJECTORY,
        width_px: 2,
    });
    chart.legend = vec![
        (
            Swatch::Line {
                color: TRAJECTORY,
                width_px: 2,
            },
            "estimated trajectory (map frame)".into(),
        ),
        (Swatch::Box([0, 0, 0]), "occupied".into()),
        (Swatch::Hollow, "free".into()),
        (Swatch::Box([205, 205, 205]), "unknown".into()),
    ];
    chart.legend.push((
        Swatch::Box([120, 120, 120]),
        format!("{width} x {height} cells of {resolution} m"),
    ));
    Ok(Some(chart))
}

/// APE translation of every associated pose against time since the first.
pub(super) fn error_chart(title: &str, detail: &RunDetail) -> Option<Chart> {
    let t0 = *detail.stamps_s.first()?;
    let points: Vec<(f64, f64)> = detail
        .stamps_s
        .iter()
        .zip(&detail.errors_m)
        .map(|(&t, &e)| (t - t0, e))
        .collect();
    let mut chart = Chart::new(title, "time (s)", "APE translation (m)");
    chart.height = eval::plot::Height::Fixed(300);
    let top = points.iter().map(|p| p.1).fold(0.0, f64::max);
    chart.y_range = Some((0.0, if top > 0.0 { top * 1.05 } else { 1.0 }));
    chart.marks.push(Mark::Line {
        points: decimate(&points, MAX_LINE_POINTS / 2),
        color: [0, 114, 178],
        width_px: 2,
    });
    Some(chart)
}

/// One run's figures for a document (`vinebench report --figures OUT RUN`), written into
/// `out`: `route.svg` (the aligned estimate over ground truth with its accepted loops and
/// the final map's wrong joins, as the report draws a scenario), `error.svg` (the APE
/// translation along the route, each accepted loop a vertical line at its time, grey if
/// true, red if false, each wrong join's later stretch an orange bar along the top), and
/// `frames/`: the pictures of its false loops and wrong joins (`frames.json`). Returns the
/// files written.
pub fn write_run_figures(
    run: &super::load::LoadedRun,
    out: &Path,
    frame_scale: u32,
) -> anyhow::Result<Vec<std::path::PathBuf>> {
    anyhow::ensure!(
        frame_scale >= 1,
        "--frame-scale {frame_scale}: a factor of 1 or more"
    );
    use super::plot::{FALSE_LOOP, TRUE_LOOP, Track, WRONG_JOIN, push_segments, scenario_chart};
    let detail = run.detail.as_ref().with_context(|| {
        format!(
            "{}: the run did not finish ({}): no figures",
            run.dir.display(),
            run.record.status.text()
        )
    })?;
    std::fs::create_dir_all(out).with_context(|| out.display().to_string())?;
    let mut written = Vec::new();
    let (scenario, plugin) = (&run.record.scenario, &run.record.plugin);

    let segments: Vec<super::plot::LoopSegment> = detail
        .loops
        .iter()
        .filter_map(|l| l.segment)
        .chain(detail.wrong_join_segments())
        .collect();
    let estimate = decimate(&run.record.estimate_xy, MAX_LINE_POINTS);
    let track = Track {
        plugin,
        plugin_index: 0,
        outcome: Ok((estimate.as_slice(), segments.as_slice())),
    };
    let mut route = scenario_chart(
        scenario,
        &decimate(&detail.groundtruth_xy, MAX_LINE_POINTS),
        &[track],
    );
    route.title = format!("{scenario}, {plugin}: aligned estimate over ground truth");
    let path = out.join("route.svg");
    route
        .save(&path, super::plot::WIDTH_PX)
        .with_context(|| path.display().to_string())?;
    written.push(path);

    let title = format!("{scenario}, {plugin}: APE translation along the route");
    let mut error = error_chart(&title, detail)
        .with_context(|| format!("{}: no associated poses", run.dir.display()))?;
    let t0 = detail.stamps_s[0];
    let top = error.y_range.map_or(1.0, |r| r.1);
    let (mut true_loops, mut false_loops) = (Vec::new(), Vec::new());
    for l in &detail.loops {
        let x = l.stamp_ns as f64 * 1e-9 - t0;
        match l.true_loop {
            Some(true) => true_loops.push([(x, 0.0), (x, top)]),
            Some(false) => false_loops.push([(x, 0.0), (x, top)]),
            None => {}
        }
    }
    let joins: Vec<[(f64, f64); 2]> = detail.joins.as_ref().map_or_else(Vec::new, |j| {
        j.report
            .wrong_joins
            .iter()
            .map(|e| {
                [
                    (e.later_s[0] - t0, 0.97 * top),
                    (e.later_s[1] - t0, 0.97 * top),
                ]
            })
            .collect()
    });
    for (segments, color, width_px, label) in [
        (true_loops, TRUE_LOOP, 1, "true loop closures"),
        (false_loops, FALSE_LOOP, 2, "false loop closures"),
        (
            joins,
            WRONG_JOIN,
            6,
            "wrong joins of the final map (its later stretch)",
        ),
    ] {
        push_segments(&mut error, segments, color, width_px, label);
    }
    let path = out.join("error.svg");
    error
        .save(&path, super::plot::WIDTH_PX)
        .with_context(|| path.display().to_string())?;
    written.push(path);

    if let Some(frames) = &detail.frames {
        for pair in frames
            .pairs
            .iter()
            .filter(|p| p.kind != crate::results::PairKind::TrueLoop)
        {
            let files = pair.files.iter().chain(&pair.matches).chain(&pair.scans);
            for file in files {
                let (from, to) = (run.dir.join(file), out.join(file));
                if let Some(parent) = to.parent() {
                    std::fs::create_dir_all(parent)
                        .with_context(|| parent.display().to_string())?;
                }
                if frame_scale == 1 {
                    std::fs::copy(&from, &to).with_context(|| {
                        format!("copying {} to {}", from.display(), to.display())
                    })?;
                } else {
                    let png = shrink_png(&from, frame_scale)
                        .with_context(|| format!("shrinking {}", from.display()))?;
                    std::fs::write(&to, png).with_context(|| to.display().to_string())?;
                }
                written.push(to);
            }
        }
    }
    Ok(written)
}

/// An 8-bit RGB PNG made `factor` times smaller each way, every output pixel the mean of
/// its `factor` x `factor` block (the last partial row and column dropped).
fn shrink_png(path: &Path, factor: u32) -> anyhow::Result<Vec<u8>> {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path)?));
    let mut reader = decoder.read_info()?;
    let mut buf = vec![0; reader.output_buffer_size().context("an image too large")?];
    let info = reader.next_frame(&mut buf)?;
    anyhow::ensure!(
        info.color_type == png::ColorType::Rgb && info.bit_depth == png::BitDepth::Eight,
        "not an 8-bit RGB PNG"
    );
    let (w, h, f) = (info.width as usize, info.height as usize, factor as usize);
    let (ow, oh) = (w / f, h / f);
    anyhow::ensure!(
        ow > 0 && oh > 0,
        "{w}x{h} is smaller than the factor {factor}"
    );
    let mut out = vec![0u8; 3 * ow * oh];
    for y in 0..oh {
        for x in 0..ow {
            for c in 0..3 {
                let sum: u32 = (0..f)
                    .flat_map(|dy| (0..f).map(move |dx| (dx, dy)))
                    .map(|(dx, dy)| u32::from(buf[3 * ((y * f + dy) * w + x * f + dx) + c]))
                    .sum();
                out[3 * (y * ow + x) + c] = ((sum + (f * f / 2) as u32) / (f * f) as u32) as u8;
            }
        }
    }
    Ok(eval::plot::encode_png(ow as u32, oh as u32, &out)?)
}

/// A binary PGM (`P5`, maxval ≤ 255): width, height, pixels row by row from the top.
fn read_pgm(path: &Path) -> anyhow::Result<(usize, usize, Vec<u8>)> {
    let bytes = std::fs::read(path).with_context(|| format!("{}: cannot read", path.display()))?;
    let bad = |why: &str| anyhow::anyhow!("{}: not a binary PGM ({why})", path.display());
    // Four whitespace-separated header tokens, then one whitespace byte, then the pixels.
    let mut tokens = Vec::new();
    let mut i = 0;
    while tokens.len() < 4 {
        while i < bytes.len() && bytes[i].is_ascii_whitespace() {
            i += 1;
        }
        let start = i;
        while i < bytes.len() && !bytes[i].is_ascii_whitespace() {
            i += 1;
        }
        if start == i {
            return Err(bad("short header"));
        }
        tokens.push(String::from_utf8_lossy(&bytes[start..i]).into_owned());
    }
    if tokens[0] != "P5" {
        return Err(bad("magic is not P5"));
    }
    let number = |s: &str| s.parse::<usize>().map_err(|_| bad("header is not numbers"));
    let (w, h, max) = (
        number(&tokens[1])?,
        number(&tokens[2])?,
        number(&tokens[3])?,
    );
    if max > 255 {
        return Err(bad("16-bit pixels"));
    }
    let data = bytes.get(i + 1..).unwrap_or_default();
    // Checked: a header's size may overflow (fuzz/regressions/report_maps/).
    if w.checked_mul(h) != Some(data.len()) {
        return Err(bad(&format!("{} pixel bytes for {w} x {h}", data.len())));
    }
    Ok((w, h, data.to_vec()))
}

/// `resolution` and `origin` (x, y) of a map_server YAML.
fn read_grid_yaml(path: &Path) -> anyhow::Result<(f64, (f64, f64))> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read", path.display()))?;
    let field = |key: &str| {
        text.lines()
            .find_map(|l| {
                l.strip_prefix(key)?
                    .trim_start()
                    .strip_prefix(':')
                    .map(str::trim)
            })
            .with_context(|| format!("{}: no {key}", path.display()))
    };
    let resolution: f64 = field("resolution")?
        .parse()
        .with_context(|| format!("{}: resolution is not a number", path.display()))?;
    let origin: Vec<f64> = field("origin")?
        .trim_matches(|c| c == '[' || c == ']')
        .split(',')
        .map(|v| v.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .with_context(|| format!("{}: origin is not [x, y, yaw]", path.display()))?;
    anyhow::ensure!(
        origin.len() >= 2 && resolution > 0.0,
        "{}: expected a positive resolution and origin [x, y, yaw]",
        path.display()
    );
    Ok((resolution, (origin[0], origin[1])))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decimation_keeps_both_ends_and_the_bound() {
        let v: Vec<usize> = (0..1001).collect();
        let d = decimate(&v, 100);
        assert!(d.len() <= 100, "{}", d.len());
        assert_eq!((d[0], *d.last().unwrap()), (0, 1000));
        assert_eq!(decimate(&v[..10], 100).len(), 10);
    }

    /// A header whose size overflows is refused, not taken for the pixels it wraps to
    /// (2^63 x 2 wraps to 0, the bytes this file has; the fuzzer's input is in
    /// fuzz/regressions/report_maps/).
    #[test]
    fn a_pgm_whose_size_overflows_is_refused() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("grid.pgm");
        std::fs::write(&path, b"P5\n9223372036854775808 2\n255\n").expect("write");
        let err = read_pgm(&path).expect_err("overflowing size").to_string();
        assert!(
            err.contains("0 pixel bytes for 9223372036854775808 x 2"),
            "{err}"
        );
    }

    #[test]
    fn grids_read_back_as_written() {
        let dir = tempfile::tempdir().unwrap();
        let grid = plugin_api::OccupancyGrid {
            width: 3,
            height: 2,
            resolution_m: 0.5,
            origin: [-1.0, 2.0, 0.0],
            cells: vec![-1, 0, 100, 100, 0, -1],
        };
        let (pgm, yaml) = (dir.path().join("g.pgm"), dir.path().join("g.yaml"));
        crate::results::write_grid(&pgm, &yaml, &grid).unwrap();
        let (w, h, px) = read_pgm(&pgm).unwrap();
        assert_eq!((w, h), (3, 2));
        // The last grid row first.
        assert_eq!(px, [0, 254, 205, 205, 254, 0]);
        assert_eq!(read_grid_yaml(&yaml).unwrap(), (0.5, (-1.0, 2.0)));
        std::fs::write(&pgm, b"P2\n3 2\n255\n").unwrap();
        assert!(read_pgm(&pgm).unwrap_err().to_string().contains("g.pgm"));
    }
}

/// The colour a GNSS fix status (by name, best first) is drawn in, on the report's maps and
/// `vinebench gnss-map`'s.
pub const FIX_COLOURS: [(&str, &str); 4] = [
    ("fixed", "#1a9850"),
    ("float", "#fdae61"),
    ("single", "#d73027"),
    ("none", "#000000"),
];

/// A run's fix-quality map: its true route (grey) and each GNSS epoch fed to the plugin as
/// a dot at the truth's position then, coloured by its fix status, with each status's share
/// of the epochs in the legend. `None` without epochs.
pub fn gnss_svg(
    route: &[(f64, f64)],
    epochs: &[(f64, f64, String)],
    width_px: f64,
) -> Option<String> {
    use std::fmt::Write as _;
    if epochs.is_empty() {
        return None;
    }
    let points = route
        .iter()
        .copied()
        .chain(epochs.iter().map(|e| (e.0, e.1)));
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for (x, y) in points {
        (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
    }
    let margin = 10.0;
    let scale = (width_px - 2.0 * margin) / (x1 - x0).max(y1 - y0).max(1.0);
    let height = (y1 - y0).max(1.0) * scale + 2.0 * margin + 24.0;
    let px = |x: f64| margin + (x - x0) * scale;
    let py = |y: f64| margin + (y1 - y) * scale;
    let mut s = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{width_px:.0}\" height=\"{height:.0}\" \
         font-family=\"sans-serif\" font-size=\"12\">\n<polyline fill=\"none\" stroke=\"#bbb\" \
         stroke-width=\"2\" points=\""
    );
    for &(x, y) in route {
        let _ = write!(s, "{:.1},{:.1} ", px(x), py(y));
    }
    s.push_str("\"/>\n");
    for (x, y, status) in epochs {
        let colour = FIX_COLOURS
            .iter()
            .find(|(name, _)| name == status)
            .map_or("#888", |(_, c)| c);
        let _ = writeln!(
            s,
            "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"2\" fill=\"{colour}\"/>",
            px(*x),
            py(*y)
        );
    }
    let mut legend = String::new();
    for (name, colour) in FIX_COLOURS {
        let n = epochs.iter().filter(|e| e.2 == name).count();
        if n > 0 {
            let share = 100.0 * n as f64 / epochs.len() as f64;
            let _ = write!(
                legend,
                " <tspan fill=\"{colour}\">● {name} {share:.1} %</tspan>"
            );
        }
    }
    let _ = writeln!(
        s,
        "<text x=\"{margin}\" y=\"{:.0}\">GNSS fix:{legend}</text>\n</svg>",
        height - 8.0
    );
    Some(s)
}

#[cfg(test)]
mod gnss_tests {
    use super::*;

    /// Three fixed epochs and one float along a route: four dots in their statuses'
    /// colours, the legend's shares 75 % and 25 %, no share for a status never seen; no
    /// figure without epochs.
    #[test]
    fn the_fix_map_colours_each_epoch_and_gives_the_shares() {
        let route = [(0.0, 0.0), (10.0, 0.0), (10.0, 5.0)];
        let epochs: Vec<(f64, f64, String)> = [(0.0, 0.0), (5.0, 0.0), (10.0, 0.0)]
            .iter()
            .map(|&(x, y)| (x, y, "fixed".to_owned()))
            .chain([(10.0, 5.0, "float".to_owned())])
            .collect();
        let svg = gnss_svg(&route, &epochs, 400.0).expect("a figure");
        assert_eq!(svg.matches("fill=\"#1a9850\"/>").count(), 3, "{svg}");
        assert_eq!(svg.matches("fill=\"#fdae61\"/>").count(), 1, "{svg}");
        assert!(
            svg.contains("fixed 75.0 %") && svg.contains("float 25.0 %"),
            "{svg}"
        );
        assert!(!svg.contains("single"), "{svg}");
        assert!(gnss_svg(&route, &[], 400.0).is_none());
    }
}
