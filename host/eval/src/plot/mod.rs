//! Plots drawn with `plotters`: a [`Chart`] (title, axes with their units, grid, legend,
//! optional colour bar) rendered to SVG or PNG from one description, text in DejaVu Sans,
//! which this crate bundles (`assets/fonts`, Bitstream Vera licence), so a PNG has the
//! same title, axis labels and legend as its SVG on any machine, without fontconfig.

mod chart;
mod colormap;
mod trajectory;

pub use chart::{Chart, ColorBar, Height, Mark, Swatch, encode_png};
pub use colormap::viridis;
pub use trajectory::{error_colored_path, plot_trajectories};

/// An RGB colour.
pub type Rgb = [u8; 3];

/// DejaVu Sans 2.37, from Debian's fonts-dejavu-core.
static DEJAVU_SANS: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");

/// Registers the bundled font as `plotters`' "sans-serif", once per process.
fn register_font() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        plotters::style::register_font(
            "sans-serif",
            plotters::style::FontStyle::Normal,
            DEJAVU_SANS,
        )
        .unwrap_or_else(|_| panic!("the bundled DejaVu Sans is a valid TrueType font"));
    });
}
