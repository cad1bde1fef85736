//! A [`Chart`]: a titled x–y plot with axes, a grid and a legend, rendered by `plotters`
//! to SVG (vector, text as `<text>`) or PNG (text rasterised with the bundled DejaVu Sans),
//! from one description, so both show the same thing.
//!
//! Layout, top to bottom: the title, the plot area framed by its axes (ticks and labels in
//! the data's units, a light grid), and a legend band below the plot that names every
//! entry (and, if the chart has one, a colour bar), so the legend never hides data.

use plotters::coord::Shift;
use plotters::prelude::*;

use super::{Rgb, viridis};
use crate::EvalError;

const FONT: &str = "sans-serif";
const TITLE_PX: f64 = 20.0;
const LABEL_PX: f64 = 15.0;
const TICK_PX: f64 = 13.0;
const MARGIN_PX: u32 = 12;
const CAPTION_PX: u32 = 34;
const X_LABEL_AREA_PX: u32 = 48;
const Y_LABEL_AREA_PX: u32 = 72;
const LEGEND_ROW_PX: u32 = 24;
const LEGEND_PAD_PX: u32 = 10;
const COLORBAR_ROW_PX: u32 = 44;
const SWATCH_PX: i32 = 28;

/// How tall the picture is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Height {
    /// The whole picture this many pixels tall.
    Fixed(u32),
    /// One metre on x is as long as one metre on y (maps, top views): the plot area's
    /// height follows the data's aspect within these limits (pixels), and the range of
    /// the other axis is widened to keep the scale equal.
    EqualAspect { min_plot_px: u32, max_plot_px: u32 },
}

/// Something drawn in the plot area, in data coordinates.
#[derive(Debug, Clone, PartialEq)]
pub enum Mark {
    /// A polyline.
    Line {
        points: Vec<(f64, f64)>,
        color: Rgb,
        width_px: u32,
    },
    /// Separate straight segments of one colour.
    Segments {
        segments: Vec<[(f64, f64); 2]>,
        color: Rgb,
        width_px: u32,
    },
    /// Straight segments, each in its own colour (a path coloured by a value).
    ColoredSegments {
        segments: Vec<([(f64, f64); 2], Rgb)>,
        width_px: u32,
    },
    /// Filled circles of one colour.
    Dots {
        points: Vec<(f64, f64)>,
        color: Rgb,
        radius_px: u32,
    },
    /// Single pixels, each in its own colour (point clouds); drawn in PNG only, since a
    /// vector picture of a whole map would be megabytes. An SVG chart with pixels is an
    /// error.
    Pixels { points: Vec<((f64, f64), Rgb)> },
    /// Filled axis-aligned rectangles between two corners (cells of a grid).
    Rects { rects: Vec<([(f64, f64); 2], Rgb)> },
    /// A line through the means with vertical bars from low to high: `(x, low, mean,
    /// high)`.
    ErrorBars {
        points: Vec<(f64, f64, f64, f64)>,
        color: Rgb,
    },
}

/// What a legend entry shows before its label.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Swatch {
    Line {
        color: Rgb,
        width_px: u32,
    },
    Box(Rgb),
    /// A hollow grey box: an entry with nothing drawn (e.g. a system that failed).
    Hollow,
}

/// A colour bar under the plot: viridis from `min` (dark) to `max` (yellow).
#[derive(Debug, Clone, PartialEq)]
pub struct ColorBar {
    pub label: String,
    pub min: f64,
    pub max: f64,
}

/// A plot, independent of the output format.
#[derive(Debug, Clone, PartialEq)]
pub struct Chart {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    /// Drawn in order, so later marks lie on top.
    pub marks: Vec<Mark>,
    pub legend: Vec<(Swatch, String)>,
    pub color_bar: Option<ColorBar>,
    /// The axes' ranges; `None`: the data's, with a margin of 4 % of the larger span.
    pub x_range: Option<(f64, f64)>,
    pub y_range: Option<(f64, f64)>,
    /// Named x values: a mark at x = i sits at `x_categories[i]`, the x axis spans
    /// `-0.5..n-0.5` and is labelled with the names (an axis of a sweep). Empty: numeric.
    pub x_categories: Vec<String>,
    pub height: Height,
}

impl Chart {
    /// An empty chart with a title and axis labels, a fixed height.
    pub fn new(
        title: impl Into<String>,
        x_label: impl Into<String>,
        y_label: impl Into<String>,
    ) -> Self {
        Self {
            title: title.into(),
            x_label: x_label.into(),
            y_label: y_label.into(),
            marks: Vec::new(),
            legend: Vec::new(),
            color_bar: None,
            x_range: None,
            y_range: None,
            x_categories: Vec::new(),
            height: Height::Fixed(500),
        }
    }

    /// A top view in metres with equal scales on both axes.
    pub fn top_view(title: impl Into<String>) -> Self {
        Self {
            height: Height::EqualAspect {
                min_plot_px: 260,
                max_plot_px: 900,
            },
            ..Self::new(title, "x (m)", "y (m)")
        }
    }

    /// Renders the chart `width_px` wide as an SVG document.
    pub fn to_svg(&self, width_px: u32) -> Result<String, EvalError> {
        if self.marks.iter().any(|m| matches!(m, Mark::Pixels { .. })) {
            return Err(self.error("point clouds are drawn in PNG only"));
        }
        let layout = self.layout(width_px)?;
        let mut svg = String::new();
        {
            let root =
                SVGBackend::with_string(&mut svg, (width_px, layout.height)).into_drawing_area();
            self.draw(&root, &layout)?;
            root.present().map_err(plot_error)?;
        }
        Ok(svg)
    }

    /// Renders the chart `width_px` wide as PNG bytes (RGB, 8 bits).
    pub fn to_png(&self, width_px: u32) -> Result<Vec<u8>, EvalError> {
        let layout = self.layout(width_px)?;
        let mut rgb = vec![255u8; width_px as usize * layout.height as usize * 3];
        {
            let root =
                BitMapBackend::with_buffer(&mut rgb, (width_px, layout.height)).into_drawing_area();
            self.draw(&root, &layout)?;
            root.present().map_err(plot_error)?;
        }
        encode_png(width_px, layout.height, &rgb)
    }

    /// Writes PNG or SVG, chosen by `path`'s extension.
    pub fn save(&self, path: &std::path::Path, width_px: u32) -> Result<(), EvalError> {
        let bytes = match path.extension().and_then(|e| e.to_str()) {
            Some(e) if e.eq_ignore_ascii_case("svg") => self.to_svg(width_px)?.into_bytes(),
            Some(e) if e.eq_ignore_ascii_case("png") => self.to_png(width_px)?,
            _ => {
                return Err(EvalError::Encode {
                    path: path.to_path_buf(),
                    message: "unknown image type: use a .png or .svg extension".into(),
                });
            }
        };
        std::fs::write(path, bytes).map_err(|source| EvalError::Write {
            path: path.to_path_buf(),
            source,
        })
    }

    fn error(&self, message: impl Into<String>) -> EvalError {
        EvalError::Plot {
            title: self.title.clone(),
            message: message.into(),
        }
    }

    /// Data ranges, the picture's height and the legend's rows.
    fn layout(&self, width_px: u32) -> Result<Layout, EvalError> {
        super::register_font();
        let (mut x, mut y) = self.ranges().ok_or_else(|| self.error("nothing to plot"))?;
        let plot_w = f64::from(
            width_px
                .saturating_sub(Y_LABEL_AREA_PX + 2 * MARGIN_PX)
                .max(50),
        );
        let plot_h = match self.height {
            Height::Fixed(h) => f64::from(h),
            Height::EqualAspect {
                min_plot_px,
                max_plot_px,
            } => {
                let (dx, dy) = (x.1 - x.0, y.1 - y.0);
                let h = (plot_w * dy / dx).clamp(f64::from(min_plot_px), f64::from(max_plot_px));
                // Widen the range that is too short for an equal scale.
                let scale = (dx / plot_w).max(dy / h);
                let grow = |r: (f64, f64), px: f64| {
                    let (c, half) = (0.5 * (r.0 + r.1), 0.5 * scale * px);
                    (c - half, c + half)
                };
                x = grow(x, plot_w);
                y = grow(y, h);
                h.round()
            }
        };
        let legend_rows = self.legend_rows(width_px);
        let legend_px = if legend_rows.is_empty() && self.color_bar.is_none() {
            0
        } else {
            2 * LEGEND_PAD_PX
                + LEGEND_ROW_PX * legend_rows.len() as u32
                + if self.color_bar.is_some() {
                    COLORBAR_ROW_PX
                } else {
                    0
                }
        };
        let chart_px = match self.height {
            Height::Fixed(h) => h,
            Height::EqualAspect { .. } => {
                plot_h as u32 + CAPTION_PX + X_LABEL_AREA_PX + 2 * MARGIN_PX
            }
        };
        Ok(Layout {
            x,
            y,
            chart_px,
            height: chart_px + legend_px,
            legend_rows,
        })
    }

    /// The legend's entries flowed into rows that fit `width_px`.
    fn legend_rows(&self, width_px: u32) -> Vec<Vec<usize>> {
        let avail = width_px.saturating_sub(2 * MARGIN_PX) as i32;
        let mut rows: Vec<Vec<usize>> = Vec::new();
        let mut used = 0;
        for (i, (_, label)) in self.legend.iter().enumerate() {
            let w = entry_width(label);
            match rows.last_mut() {
                Some(row) if used + w <= avail => {
                    row.push(i);
                    used += w;
                }
                _ => {
                    rows.push(vec![i]);
                    used = w;
                }
            }
        }
        rows
    }

    /// The data's bounding box with a margin, or the fixed ranges.
    fn ranges(&self) -> Option<((f64, f64), (f64, f64))> {
        let mut b = Bounds::default();
        for mark in &self.marks {
            match mark {
                Mark::Line { points, .. } | Mark::Dots { points, .. } => {
                    points.iter().for_each(|&p| b.add(p))
                }
                Mark::Segments { segments, .. } => {
                    segments.iter().flatten().for_each(|&p| b.add(p))
                }
                Mark::ColoredSegments { segments, .. } => {
                    segments.iter().flat_map(|(s, _)| s).for_each(|&p| b.add(p));
                }
                Mark::Pixels { points } => points.iter().for_each(|&(p, _)| b.add(p)),
                Mark::Rects { rects } => rects.iter().flat_map(|(r, _)| r).for_each(|&p| b.add(p)),
                Mark::ErrorBars { points, .. } => points.iter().for_each(|&(x, lo, mean, hi)| {
                    for y in [lo, mean, hi] {
                        b.add((x, y));
                    }
                }),
            }
        }
        let data = b.get();
        let pad = |r: (f64, f64), span: f64| (r.0 - 0.04 * span, r.1 + 0.04 * span);
        let categories =
            (!self.x_categories.is_empty()).then(|| (-0.5, self.x_categories.len() as f64 - 0.5));
        let (x, y) = match (categories.or(self.x_range), self.y_range, data) {
            (Some(x), Some(y), _) => (x, y),
            (fx, fy, Some((x, y))) => {
                let span = (x.1 - x.0).max(y.1 - y.0).max(1e-3);
                let (x, y) = match self.height {
                    Height::EqualAspect { .. } => (pad(x, span), pad(y, span)),
                    Height::Fixed(_) => {
                        (pad(x, (x.1 - x.0).max(1e-3)), pad(y, (y.1 - y.0).max(1e-3)))
                    }
                };
                (fx.unwrap_or(x), fy.unwrap_or(y))
            }
            _ => return None,
        };
        let widen = |r: (f64, f64)| {
            if r.1 - r.0 < 1e-9 {
                (r.0 - 0.5, r.1 + 0.5)
            } else {
                r
            }
        };
        Some((widen(x), widen(y)))
    }

    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        layout: &Layout,
    ) -> Result<(), EvalError> {
        root.fill(&WHITE).map_err(plot_error)?;
        let (plot_area, legend_area) = root.split_vertically(layout.chart_px);
        let mut chart = ChartBuilder::on(&plot_area)
            .caption(&self.title, (FONT, TITLE_PX))
            .margin(MARGIN_PX)
            .x_label_area_size(X_LABEL_AREA_PX)
            .y_label_area_size(Y_LABEL_AREA_PX)
            .build_cartesian_2d(layout.x.0..layout.x.1, layout.y.0..layout.y.1)
            .map_err(plot_error)?;
        let category = |v: &f64| {
            let i = v.round();
            if (v - i).abs() < 1e-6 && i >= 0.0 {
                self.x_categories
                    .get(i as usize)
                    .cloned()
                    .unwrap_or_default()
            } else {
                String::new()
            }
        };
        let mut mesh = chart.configure_mesh();
        if self.x_categories.is_empty() {
            mesh.x_label_formatter(&|v| tick(*v));
        } else {
            mesh.x_labels(self.x_categories.len() + 1)
                .x_label_formatter(&category)
                .disable_x_mesh();
        }
        mesh.x_desc(&self.x_label)
            .y_desc(&self.y_label)
            .axis_desc_style((FONT, LABEL_PX))
            .label_style((FONT, TICK_PX))
            .bold_line_style(RGBColor(215, 215, 215))
            .light_line_style(RGBColor(242, 242, 242))
            .max_light_lines(1)
            .y_label_formatter(&|v| tick(*v))
            .draw()
            .map_err(plot_error)?;
        for mark in &self.marks {
            match mark {
                Mark::Line {
                    points,
                    color,
                    width_px,
                } => {
                    chart
                        .draw_series(std::iter::once(PathElement::new(
                            points.clone(),
                            rgb(*color).stroke_width(*width_px),
                        )))
                        .map_err(plot_error)?;
                }
                Mark::Segments {
                    segments,
                    color,
                    width_px,
                } => {
                    let style = rgb(*color).stroke_width(*width_px);
                    chart
                        .draw_series(segments.iter().map(|s| PathElement::new(s.to_vec(), style)))
                        .map_err(plot_error)?;
                }
                Mark::ColoredSegments { segments, width_px } => {
                    chart
                        .draw_series(segments.iter().map(|(s, c)| {
                            PathElement::new(s.to_vec(), rgb(*c).stroke_width(*width_px))
                        }))
                        .map_err(plot_error)?;
                }
                Mark::Dots {
                    points,
                    color,
                    radius_px,
                } => {
                    let style = rgb(*color).filled();
                    chart
                        .draw_series(points.iter().map(|&p| Circle::new(p, *radius_px, style)))
                        .map_err(plot_error)?;
                }
                Mark::Pixels { points } => {
                    chart
                        .draw_series(points.iter().map(|&(p, c)| Pixel::new(p, rgb(c))))
                        .map_err(plot_error)?;
                }
                Mark::Rects { rects } => {
                    chart
                        .draw_series(
                            rects
                                .iter()
                                .map(|&(r, c)| Rectangle::new(r, rgb(c).filled())),
                        )
                        .map_err(plot_error)?;
                }
                Mark::ErrorBars { points, color } => {
                    let style = rgb(*color).stroke_width(2);
                    chart
                        .draw_series(std::iter::once(PathElement::new(
                            points
                                .iter()
                                .map(|&(x, _, m, _)| (x, m))
                                .collect::<Vec<_>>(),
                            style,
                        )))
                        .map_err(plot_error)?;
                    chart
                        .draw_series(
                            points.iter().map(|&(x, lo, m, hi)| {
                                ErrorBar::new_vertical(x, lo, m, hi, style, 10)
                            }),
                        )
                        .map_err(plot_error)?;
                }
            }
        }
        self.draw_legend(&legend_area, layout)
    }

    fn draw_legend<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, Shift>,
        layout: &Layout,
    ) -> Result<(), EvalError> {
        let text = TextStyle::from((FONT, LABEL_PX).into_font()).color(&BLACK);
        let x0 = MARGIN_PX as i32 + Y_LABEL_AREA_PX as i32 / 2;
        let mut y = LEGEND_PAD_PX as i32 + LEGEND_ROW_PX as i32 / 2;
        for row in &layout.legend_rows {
            let mut x = x0;
            for &i in row {
                let (swatch, label) = &self.legend[i];
                match *swatch {
                    Swatch::Line { color, width_px } => area.draw(&PathElement::new(
                        vec![(x, y), (x + SWATCH_PX, y)],
                        rgb(color).stroke_width(width_px.max(2)),
                    )),
                    Swatch::Box(color) => area.draw(&Rectangle::new(
                        [(x + 4, y - 7), (x + SWATCH_PX - 4, y + 7)],
                        rgb(color).filled(),
                    )),
                    Swatch::Hollow => area.draw(&Rectangle::new(
                        [(x + 4, y - 7), (x + SWATCH_PX - 4, y + 7)],
                        RGBColor(150, 150, 150).stroke_width(2),
                    )),
                }
                .map_err(plot_error)?;
                area.draw(&Text::new(
                    label.clone(),
                    (x + SWATCH_PX + 6, y - LABEL_PX as i32 / 2 - 1),
                    text.clone(),
                ))
                .map_err(plot_error)?;
                x += entry_width(label);
            }
            y += LEGEND_ROW_PX as i32;
        }
        if let Some(bar) = &self.color_bar {
            let (w, _) = area.dim_in_pixel();
            let left = x0 + 80;
            let right = (w as i32 - MARGIN_PX as i32 - 80).max(left + 50);
            let top = y - LEGEND_ROW_PX as i32 / 2 + 4;
            for px in left..right {
                let t = f64::from(px - left) / f64::from(right - left - 1).max(1.0);
                area.draw(&PathElement::new(
                    vec![(px, top), (px, top + 14)],
                    rgb(viridis(t)),
                ))
                .map_err(plot_error)?;
            }
            let small = TextStyle::from((FONT, TICK_PX).into_font()).color(&BLACK);
            area.draw(&Text::new(tick(bar.min), (x0, top), small.clone()))
                .map_err(plot_error)?;
            area.draw(&Text::new(tick(bar.max), (right + 8, top), small))
                .map_err(plot_error)?;
            let (tw, _) = area
                .estimate_text_size(&bar.label, &text)
                .map_err(plot_error)?;
            area.draw(&Text::new(
                bar.label.clone(),
                ((left + right) / 2 - tw as i32 / 2, top + 18),
                text,
            ))
            .map_err(plot_error)?;
        }
        Ok(())
    }
}

struct Layout {
    x: (f64, f64),
    y: (f64, f64),
    /// Height of the title, plot and axes; the legend band comes below.
    chart_px: u32,
    height: u32,
    legend_rows: Vec<Vec<usize>>,
}

#[derive(Default)]
struct Bounds(Option<((f64, f64), (f64, f64))>);

impl Bounds {
    fn add(&mut self, (x, y): (f64, f64)) {
        if !(x.is_finite() && y.is_finite()) {
            return;
        }
        self.0 = Some(match self.0 {
            None => ((x, x), (y, y)),
            Some(((x0, x1), (y0, y1))) => ((x0.min(x), x1.max(x)), (y0.min(y), y1.max(y))),
        });
    }

    fn get(&self) -> Option<((f64, f64), (f64, f64))> {
        self.0
    }
}

/// A legend entry's width: swatch, gap, the label's width (DejaVu Sans averages about
/// 0.6 em per character) and the space to the next entry.
fn entry_width(label: &str) -> i32 {
    SWATCH_PX + 6 + (label.chars().count() as f64 * LABEL_PX * 0.6).ceil() as i32 + 28
}

/// Tick labels: at most 3 decimals, no trailing zeros, no "-0".
fn tick(v: f64) -> String {
    let s = format!("{v:.3}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" {
        "0".to_owned()
    } else {
        s.to_owned()
    }
}

fn rgb(c: Rgb) -> RGBColor {
    RGBColor(c[0], c[1], c[2])
}

fn plot_error<E: std::error::Error + Send + Sync>(e: DrawingAreaErrorKind<E>) -> EvalError {
    EvalError::Plot {
        title: String::new(),
        message: e.to_string(),
    }
}

/// 8-bit RGB PNG, default compression: the same pixels give the same bytes.
pub fn encode_png(width: u32, height: u32, rgb: &[u8]) -> Result<Vec<u8>, EvalError> {
    let mut out = Vec::new();
    let mut encoder = png::Encoder::new(&mut out, width, height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header().map_err(png_error)?;
    writer.write_image_data(rgb).map_err(png_error)?;
    writer.finish().map_err(png_error)?;
    Ok(out)
}

fn png_error(e: png::EncodingError) -> EvalError {
    EvalError::Plot {
        title: String::new(),
        message: format!("encoding a PNG: {e}"),
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// The contents of the SVG's `<text>` elements.
    pub(crate) fn svg_texts(svg: &str) -> Vec<&str> {
        svg.split("</text>")
            .filter_map(|chunk| chunk.rfind("<text").map(|i| &chunk[i..]))
            .filter_map(|t| t.split_once('>').map(|(_, body)| body.trim()))
            .collect()
    }

    fn chart() -> Chart {
        let mut c = Chart::top_view("S9: a test");
        c.marks.push(Mark::Line {
            points: vec![(0.0, 0.0), (10.0, 2.0), (20.0, 0.0)],
            color: [0, 0, 0],
            width_px: 3,
        });
        c.legend.push((
            Swatch::Line {
                color: [0, 0, 0],
                width_px: 3,
            },
            "ground truth".into(),
        ));
        c.legend
            .push((Swatch::Hollow, "broken-system (failed)".into()));
        c
    }

    #[test]
    fn svg_names_title_axes_and_legend() {
        let svg = chart().to_svg(800).unwrap();
        let texts = svg_texts(&svg);
        for text in [
            "S9: a test",
            "x (m)",
            "y (m)",
            "ground truth",
            "broken-system (failed)",
            "10",
        ] {
            assert!(
                texts.contains(&text),
                "{text:?} missing from the SVG's texts {texts:?}"
            );
        }
    }

    #[test]
    fn png_has_text_pixels_and_is_deterministic() {
        let c = chart();
        let a = c.to_png(800).unwrap();
        assert_eq!(a, c.to_png(800).unwrap());
        let decoder = png::Decoder::new(std::io::Cursor::new(&a));
        let mut reader = decoder.read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut buf).unwrap();
        // The title band (above the plot area) holds only the title's glyphs: dark
        // pixels there mean the PNG draws text.
        let row = info.width as usize * 3;
        let dark = buf[..row * CAPTION_PX as usize]
            .chunks(3)
            .filter(|p| p.iter().all(|&v| v < 100))
            .count();
        assert!(dark > 50, "only {dark} dark pixels in the title band");
    }

    #[test]
    fn equal_aspect_keeps_metres_square() {
        let c = chart();
        let layout = c.layout(800).unwrap();
        let plot_w = f64::from(800 - Y_LABEL_AREA_PX - 2 * MARGIN_PX);
        let plot_h = f64::from(layout.chart_px - CAPTION_PX - X_LABEL_AREA_PX - 2 * MARGIN_PX);
        let sx = (layout.x.1 - layout.x.0) / plot_w;
        let sy = (layout.y.1 - layout.y.0) / plot_h;
        assert!((sx - sy).abs() / sx < 0.01, "{sx} m/px on x, {sy} on y");
    }

    #[test]
    fn point_clouds_are_png_only_and_empty_charts_are_refused() {
        let mut c = chart();
        c.marks.push(Mark::Pixels {
            points: vec![((1.0, 1.0), [1, 2, 3])],
        });
        assert!(c.to_svg(600).is_err());
        assert!(c.to_png(600).is_ok());
        assert!(Chart::new("empty", "x", "y").to_png(600).is_err());
    }
}
