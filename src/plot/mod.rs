//! Figures as PNG and SVG: field images (heat maps with a colour bar) and x–y line/scatter
//! plots, plus the cross-sections of cylinders to outline particles on a field image.
//!
//! Two kinds of figure, each drawn by one layout routine that is generic over the drawing
//! backend: into an in-memory RGB buffer encoded as an 8-bit RGB PNG, or into an SVG
//! document (through this module's own small SVG backend, which needs neither plotters'
//! `svg_backend` nor an image library); either is written atomically
//! ([`crate::io::atomic_write_bytes`]):
//!
//! - [`write_field_png`] / [`write_field_svg`]: a scalar field on a 2-D grid of nodes (for
//!   instance the speed `|u| / v_tip` on the vertical mid-plane through the impeller axis,
//!   the paper's Figures 3 and 4), coloured with the perceptually uniform viridis map
//!   ([`viridis`]), with equal aspect ratio of the physical extent, ticked axes, a ticked
//!   colour bar and optional outlines (the particles' sections, [`cylinder_section`]);
//! - [`write_line_png`] / [`write_line_svg`]: one or more x–y [`Series`] (lines, markers or
//!   both) with a legend, axis labels, optional fixed ranges and optional logarithmic axes
//!   (time series of the power number, profiles and histograms of particle statistics).
//!
//! Text is set in DejaVu Sans, bundled with the crate (`assets/fonts/DejaVuSans.ttf`, with
//! its licence beside it, compiled in with `include_bytes!`) and registered with `plotters`
//! on first use, so that figures render identically on a machine without any system fonts
//! or fontconfig. In a PNG the glyphs are placed by this module's bitmap backend wrapper
//! (plotters' own `ab_glyph` path drops the glyphs' side bearings, "1 00" for "100"). An SVG
//! holds the text as `<text>` elements in the font family "DejaVu Sans" (falling back to
//! the viewer's sans-serif), laid out with the bundled font's metrics, so that both files
//! share one layout; the heat maps of an SVG are embedded PNG images of the same pixels as
//! the PNG figure's, not one element per node.
//!
//! Bad input (empty data, a field whose length is not `nx·ny`, `vmin ≥ vmax`, non-finite or
//! empty ranges, non-positive ranges on a logarithmic axis, sizes out of bounds) is reported
//! as a [`PlotError`] naming the file; nothing is written then, and nothing panics.

use std::io;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use plotters::element::{Drawable, PointCollection};
use plotters::prelude::*;
use plotters::style::{register_font, FontStyle};
use plotters_backend::{BackendCoord, DrawingErrorKind};

use crate::io::atomic_write_bytes;
use canvas::bundled_font;

mod canvas;
mod field;
mod line;
mod section;
mod svg;
#[cfg(test)]
mod testing;
mod ticks;

pub use field::{viridis, write_field_png, write_field_svg, FieldImage, FieldSize};
pub use line::{
    write_line_png, write_line_svg, LegendPosition, LinePlot, Series, SeriesStyle, MIN_LINE_SIDE,
};
pub use section::cylinder_section;

/// The family name under which the bundled DejaVu Sans is registered with `plotters`.
const FONT_FAMILY: &str = "slurry-dejavu-sans";

/// DejaVu Sans 2.37 (Bitstream Vera licence with DejaVu changes in the public domain; see
/// `assets/fonts/LICENSE-DejaVu.txt`).
static FONT_BYTES: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");

/// Largest width or height of a figure, in pixels (a guard against absurd allocations).
pub const MAX_SIDE: u32 = 8192;

/// Colour of a NaN node in a field image: a neutral grey, which viridis never produces.
pub const NAN_COLOR: [u8; 3] = [160, 160, 160];

/// Failure writing a figure. Every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// The figure's description is unusable (empty data, inconsistent sizes, bad ranges).
    #[error("{}: cannot plot: {reason}", path.display())]
    Input {
        /// The figure that was to be written.
        path: PathBuf,
        /// What is wrong with the input.
        reason: String,
    },
    /// The drawing library failed (font or backend error).
    #[error("{}: drawing failed: {message}", path.display())]
    Draw {
        /// The figure that was to be written.
        path: PathBuf,
        /// The library's message.
        message: String,
    },
    /// PNG encoding failed.
    #[error("{}: PNG encoding failed: {source}", path.display())]
    Encode {
        /// The figure that was to be written.
        path: PathBuf,
        /// The encoder's error.
        source: png::EncodingError,
    },
    /// File-system error (temporary file, sync, rename).
    #[error("{}: {source}", path.display())]
    Io {
        /// The figure that was to be written.
        path: PathBuf,
        /// The underlying error.
        source: io::Error,
    },
}

// ---------------------------------------------------------------------------------------------
// Shared by both kinds of figure
// ---------------------------------------------------------------------------------------------

type DrawResult<T> = Result<T, Box<dyn std::error::Error>>;

const TITLE_FONT: f64 = 20.0;
const LABEL_FONT: f64 = 16.0;
const TICK_FONT: f64 = 13.0;

/// Registers the bundled font with plotters once per process (its own text layout is
/// not used for drawing, see [`canvas::Canvas`], but the font must exist for plotters' styles).
fn ensure_font() -> Result<(), String> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let registered =
        *REGISTERED.get_or_init(|| register_font(FONT_FAMILY, FontStyle::Normal, FONT_BYTES).is_ok());
    if registered && bundled_font().is_some() {
        Ok(())
    } else {
        Err("the bundled font DejaVuSans.ttf could not be parsed".to_string())
    }
}

fn font(size: f64) -> TextStyle<'static> {
    (FONT_FAMILY, size).into_font().color(&BLACK)
}

/// Runs a renderer, turning its error or a panic inside the drawing library into
/// [`PlotError::Draw`].
fn guarded<T>(path: &Path, render: impl FnOnce() -> DrawResult<T>) -> Result<T, PlotError> {
    let draw_err = |message: String| PlotError::Draw { path: path.to_path_buf(), message };
    ensure_font().map_err(draw_err)?;
    match catch_unwind(AssertUnwindSafe(render)) {
        Ok(Ok(v)) => Ok(v),
        Ok(Err(e)) => Err(draw_err(e.to_string())),
        Err(payload) => {
            let what = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".to_string());
            Err(draw_err(format!("the drawing library panicked: {what}")))
        }
    }
}

/// Encodes an 8-bit RGB buffer (`w·h·3` bytes, rows top to bottom) as PNG.
fn encode_png(rgb: &[u8], w: u32, h: u32) -> Result<Vec<u8>, png::EncodingError> {
    let mut out = Vec::new();
    let mut enc = png::Encoder::new(&mut out, w, h);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    let mut writer = enc.write_header()?;
    writer.write_image_data(rgb)?;
    writer.finish()?;
    Ok(out)
}

/// Encodes an 8-bit RGB buffer (`w·h·3` bytes, rows top to bottom) as PNG and writes it
/// atomically to `path`.
fn write_png(path: &Path, rgb: &[u8], w: u32, h: u32) -> Result<(), PlotError> {
    let bytes =
        encode_png(rgb, w, h).map_err(|source| PlotError::Encode { path: path.to_path_buf(), source })?;
    write_bytes(path, &bytes)
}

/// Writes a finished file atomically to `path`.
fn write_bytes(path: &Path, bytes: &[u8]) -> Result<(), PlotError> {
    atomic_write_bytes(path, bytes).map_err(|source| PlotError::Io { path: path.to_path_buf(), source })
}

/// A drawing backend that can also paint a [`Raster`] over a rectangle of pixels: the
/// bitmap resamples it to the pixels, the SVG embeds it as an image.
trait Surface: DrawingBackend {
    /// Paints `raster` stretched over the `size` pixels whose upper left pixel is
    /// `upper_left`: pixel `(px, py)` of the rectangle takes the cell that holds its centre.
    fn draw_raster(
        &mut self,
        upper_left: BackendCoord,
        size: (u32, u32),
        raster: &Raster,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>>;
}

/// A grid of `cols × rows` RGB cells, rows from top to bottom (`rgb[3·(r·cols + c)..][..3]`).
struct Raster {
    cols: usize,
    rows: usize,
    rgb: Vec<u8>,
}

impl Raster {
    /// A raster of the given size from the colour of each cell `(col, row)`, row 0 at the top.
    fn from_fn(cols: usize, rows: usize, mut color: impl FnMut(usize, usize) -> RGBColor) -> Self {
        let mut rgb = Vec::with_capacity(cols * rows * 3);
        for r in 0..rows {
            for c in 0..cols {
                let RGBColor(red, green, blue) = color(c, r);
                rgb.extend_from_slice(&[red, green, blue]);
            }
        }
        Raster { cols, rows, rgb }
    }

    /// The raster resampled to `w × h` pixels (each pixel takes the cell holding its centre),
    /// as an RGB buffer.
    fn resample(&self, w: u32, h: u32) -> Vec<u8> {
        let cell =
            |p: u32, np: u32, n: usize| (((p as f64 + 0.5) / np as f64 * n as f64) as usize).min(n - 1);
        let cols: Vec<usize> = (0..w).map(|px| cell(px, w, self.cols)).collect();
        let mut out = Vec::with_capacity(w as usize * h as usize * 3);
        for py in 0..h {
            let r = cell(py, h, self.rows);
            for &c in &cols {
                let k = 3 * (r * self.cols + c);
                out.extend_from_slice(&self.rgb[k..k + 3]);
            }
        }
        out
    }
}

/// A [`Raster`] as a drawing element filling a drawing area (drawn at the area's origin).
struct RasterElement {
    raster: Raster,
    origin: BackendCoord,
    size: (u32, u32),
}

impl<'a> PointCollection<'a, BackendCoord> for &'a RasterElement {
    type Point = &'a BackendCoord;
    type IntoIter = std::iter::Once<&'a BackendCoord>;
    fn point_iter(self) -> Self::IntoIter {
        std::iter::once(&self.origin)
    }
}

impl<DB: Surface> Drawable<DB> for RasterElement {
    fn draw<I: Iterator<Item = BackendCoord>>(
        &self,
        mut points: I,
        backend: &mut DB,
        _: (u32, u32),
    ) -> Result<(), DrawingErrorKind<DB::ErrorType>> {
        match points.next() {
            Some(at) if self.raster.cols > 0 && self.raster.rows > 0 => {
                backend.draw_raster(at, self.size, &self.raster)
            }
            _ => Ok(()),
        }
    }
}

/// Fills the whole of `area` (its pixel range) with `raster`.
fn paint_raster<DB, CT>(area: &DrawingArea<DB, CT>, raster: Raster) -> DrawResult<()>
where
    DB: Surface,
    DB::ErrorType: 'static,
    CT: plotters::coord::CoordTranslate,
{
    let (xr, yr) = area.get_pixel_range();
    let size = (xr.len() as u32, yr.len() as u32);
    if size.0 == 0 || size.1 == 0 {
        return Ok(());
    }
    area.strip_coord_spec().draw(&RasterElement { raster, origin: (0, 0), size })?;
    Ok(())
}

/// A one-pixel black frame just inside the plotting area.
fn frame<DB, CT>(area: &DrawingArea<DB, CT>) -> DrawResult<()>
where
    DB: DrawingBackend,
    DB::ErrorType: 'static,
    CT: plotters::coord::CoordTranslate,
{
    let (xr, yr) = area.get_pixel_range();
    let raw = area.strip_coord_spec();
    let (w, h) = (xr.len() as i32, yr.len() as i32);
    raw.draw(&Rectangle::new([(0, 0), (w - 1, h - 1)], BLACK.stroke_width(1)))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use testing::{assert_empty, field};

    #[test]
    fn svg_input_errors_write_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bad.svg");
        let values = vec![0.0; 12];
        let bad = FieldImage { nx: 5, ..field(&values, 4, 3) };
        let err = write_field_svg(&path, &bad, FieldSize::PixelsPerNode(2)).unwrap_err();
        assert!(matches!(err, PlotError::Input { .. }) && err.to_string().contains("12 values"), "{err}");
        let plot = LinePlot { series: vec![], ..Default::default() };
        let err = write_line_svg(&path, &plot, 400, 300).unwrap_err();
        assert!(matches!(err, PlotError::Input { .. }) && err.to_string().contains("no series"), "{err}");
        assert_empty(dir.path());
        let missing = dir.path().join("no/dir/f.svg");
        let plot = LinePlot {
            series: vec![Series::new("s", vec![(0.0, 0.0), (1.0, 1.0)], SeriesStyle::Line)],
            ..Default::default()
        };
        assert!(matches!(write_line_svg(&missing, &plot, 300, 200), Err(PlotError::Io { .. })));
    }
}
