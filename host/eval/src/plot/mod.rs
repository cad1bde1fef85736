//! Small, dependency-light 2D drawing: a raster [`Canvas`] saved as PNG and an [`Svg`]
//! writer with the same primitives, both in world coordinates (x right, y up) mapped
//! uniformly (no distortion, centred) onto the picture. Generic: nothing here knows
//! about trajectories except [`plot_trajectories`].

mod bounds;
mod canvas;
mod colormap;
mod svg;
mod trajectory;

pub use bounds::Bounds;
pub use canvas::Canvas;
pub use colormap::viridis;
pub use svg::Svg;
pub use trajectory::plot_trajectories;

/// An RGB colour.
pub type Rgb = [u8; 3];

/// The primitives shared by [`Canvas`] and [`Svg`], so one drawing routine can target
/// both. Points are in world coordinates; widths and radii in pixels.
pub trait Drawing {
    /// A polyline through `points`, `width_px` wide with round joins.
    fn polyline(&mut self, points: &[(f64, f64)], color: Rgb, width_px: f64);
    /// A filled axis-aligned rectangle between two corners.
    fn fill_rect(&mut self, min: (f64, f64), max: (f64, f64), color: Rgb);
    /// A filled circle of `radius_px` pixels around `center`.
    fn circle(&mut self, center: (f64, f64), radius_px: f64, color: Rgb);
    /// The world-to-pixel mapping of the picture.
    fn bounds_mapping(&self) -> &Mapping;
}

/// The uniform mapping between world coordinates and pixels of a `width × height`
/// picture: the world bounds are scaled by the same factor on both axes and centred.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mapping {
    bounds: Bounds,
    width: u32,
    height: u32,
    px_per_unit: f64,
    offset: (f64, f64),
}

impl Mapping {
    /// The mapping of `bounds` onto a `width_px × height_px` picture.
    pub fn new(width_px: u32, height_px: u32, bounds: Bounds) -> Self {
        let (w, h) = (f64::from(width_px), f64::from(height_px));
        let (bw, bh) = (
            bounds.width().max(f64::MIN_POSITIVE),
            bounds.height().max(f64::MIN_POSITIVE),
        );
        let px_per_unit = (w / bw).min(h / bh);
        let offset = ((w - bw * px_per_unit) / 2.0, (h - bh * px_per_unit) / 2.0);
        Self {
            bounds,
            width: width_px,
            height: height_px,
            px_per_unit,
            offset,
        }
    }

    /// Pixel coordinates (x right, y down, pixel centres at +0.5) of a world point.
    pub fn to_pixel(&self, p: (f64, f64)) -> (f64, f64) {
        (
            self.offset.0 + (p.0 - self.bounds.min.0) * self.px_per_unit,
            f64::from(self.height) - self.offset.1 - (p.1 - self.bounds.min.1) * self.px_per_unit,
        )
    }

    /// The world point at pixel coordinates `px`.
    pub fn to_world(&self, px: (f64, f64)) -> (f64, f64) {
        (
            self.bounds.min.0 + (px.0 - self.offset.0) / self.px_per_unit,
            self.bounds.min.1 + (f64::from(self.height) - self.offset.1 - px.1) / self.px_per_unit,
        )
    }

    /// Pixels per world unit (metre).
    pub fn px_per_unit(&self) -> f64 {
        self.px_per_unit
    }

    /// Picture width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Picture height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The world bounds given at construction.
    pub fn bounds(&self) -> Bounds {
        self.bounds
    }
}
