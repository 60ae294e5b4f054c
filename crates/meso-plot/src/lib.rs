//! # meso-plot
//!
//! A small raster plotting library for meso's pictures, with no dependency beyond `image` (PNG
//! encoding) and `glam`:
//!
//! * [`Canvas`] — an RGB image (f32 per channel, display-referred sRGB values in `[0, 1]`) with
//!   anti-aliased lines, polylines, circles, discs, rectangles, scaled blits and PNG output;
//! * [`font`] — an embedded 5×7 bitmap font (ASCII 32..126 plus `° θ φ µ σ α π · × − – ∈ ² ³`) with
//!   proportional letters, tabular digits and integer scaling;
//! * [`ColorMap`] — viridis, magma, a diverging blue–white–red and grey, plus [`colorbar`];
//! * [`LinePlot`] and [`PolarPlot`] — axes with nice ticks, labels, legends, linear/log scales;
//!   polar slices as in the BRDF literature (radius = value, θ from the normal);
//! * [`hemisphere_map`] — a Lambert azimuthal equal-area disc of a function on the hemisphere;
//! * [`Sheet`] — a labelled contact sheet of images.
//!
//! ```
//! use meso_plot::{Canvas, color, LinePlot, Series};
//! let mut plot = LinePlot::new("cos θ");
//! plot.x_label = "θ (deg)".into();
//! plot.add(Series::new("cos", (0..=90).map(|d| [d as f64, (d as f64).to_radians().cos()]).collect()));
//! let canvas: Canvas = plot.render(480, 320).unwrap();
//! assert_eq!(canvas.width(), 480);
//! let png = canvas.to_png_bytes().unwrap();
//! assert_eq!(&png[1..4], b"PNG");
//! # let _ = color::WHITE;
//! ```
#![warn(missing_docs)]

mod canvas;
pub mod color;
mod colormap;
pub mod font;
mod plot;
mod polar;
mod sheet;
mod sphere;
pub mod ticks;

pub use canvas::{Canvas, Filter, Rect};
pub use color::Rgb;
pub use colormap::{colorbar, colorbar_extent, colorbar_scaled, ColorMap, ValueScale};
pub use font::{draw_text, text_width, Anchor};
pub use plot::{LinePlot, LineStyle, Series};
pub use polar::{PolarPlot, PolarSeries};
pub use sheet::Sheet;
pub use sphere::{hemisphere_map, hemisphere_map_range, DiscGeometry, SphereMap};

/// Errors of the plotting library.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// Writing a file failed.
    #[error("i/o error: {0}")]
    Io(#[from] std::io::Error),
    /// PNG encoding failed.
    #[error("png encoding failed: {0}")]
    Png(String),
    /// A raw pixel buffer does not match its stated size.
    #[error("pixel buffer has {got} values, expected {expected} ({width}×{height}×3)")]
    BufferSize {
        /// Stated width.
        width: u32,
        /// Stated height.
        height: u32,
        /// Expected number of values.
        expected: usize,
        /// Actual number of values.
        got: usize,
    },
    /// An image size is zero or larger than [`Canvas::MAX_SIDE`].
    #[error("invalid image size {width}×{height}")]
    InvalidSize {
        /// Requested width.
        width: u32,
        /// Requested height.
        height: u32,
    },
    /// A plot has nothing finite (or, for a log axis, nothing positive) to show.
    #[error("no plottable data: {0}")]
    NoData(String),
    /// A parameter is out of its valid range.
    #[error("invalid parameter: {0}")]
    Invalid(String),
}
