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

use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::element::{Drawable, PointCollection};
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::{register_font, FontStyle, FontTransform};

use crate::io::atomic_write_bytes;
use canvas::{bundled_font, Canvas};
use plotters_backend::{BackendCoord, DrawingErrorKind};
use svg::SvgCanvas;

mod section;
mod svg;

pub use section::cylinder_section;

/// The family name under which the bundled DejaVu Sans is registered with `plotters`.
const FONT_FAMILY: &str = "slurry-dejavu-sans";

/// DejaVu Sans 2.37 (Bitstream Vera licence with DejaVu changes in the public domain; see
/// `assets/fonts/LICENSE-DejaVu.txt`).
static FONT_BYTES: &[u8] = include_bytes!("../assets/fonts/DejaVuSans.ttf");

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
// Colour map
// ---------------------------------------------------------------------------------------------

/// The viridis colour map (van der Walt & Smith, CC0), matplotlib's 256 entries rounded to
/// 8 bits: entry `k` is the colour of `t = k / 255`.
#[rustfmt::skip]
static VIRIDIS: [[u8; 3]; 256] = [
    [68, 1, 84], [68, 2, 86], [69, 4, 87], [69, 5, 89], [70, 7, 90], [70, 8, 92], [70, 10, 93], [70, 11, 94],
    [71, 13, 96], [71, 14, 97], [71, 16, 99], [71, 17, 100], [71, 19, 101], [72, 20, 103], [72, 22, 104], [72, 23, 105],
    [72, 24, 106], [72, 26, 108], [72, 27, 109], [72, 28, 110], [72, 29, 111], [72, 31, 112], [72, 32, 113], [72, 33, 115],
    [72, 35, 116], [72, 36, 117], [72, 37, 118], [72, 38, 119], [72, 40, 120], [72, 41, 121], [71, 42, 122], [71, 44, 122],
    [71, 45, 123], [71, 46, 124], [71, 47, 125], [70, 48, 126], [70, 50, 126], [70, 51, 127], [70, 52, 128], [69, 53, 129],
    [69, 55, 129], [69, 56, 130], [68, 57, 131], [68, 58, 131], [68, 59, 132], [67, 61, 132], [67, 62, 133], [66, 63, 133],
    [66, 64, 134], [66, 65, 134], [65, 66, 135], [65, 68, 135], [64, 69, 136], [64, 70, 136], [63, 71, 136], [63, 72, 137],
    [62, 73, 137], [62, 74, 137], [62, 76, 138], [61, 77, 138], [61, 78, 138], [60, 79, 138], [60, 80, 139], [59, 81, 139],
    [59, 82, 139], [58, 83, 139], [58, 84, 140], [57, 85, 140], [57, 86, 140], [56, 88, 140], [56, 89, 140], [55, 90, 140],
    [55, 91, 141], [54, 92, 141], [54, 93, 141], [53, 94, 141], [53, 95, 141], [52, 96, 141], [52, 97, 141], [51, 98, 141],
    [51, 99, 141], [50, 100, 142], [50, 101, 142], [49, 102, 142], [49, 103, 142], [49, 104, 142], [48, 105, 142], [48, 106, 142],
    [47, 107, 142], [47, 108, 142], [46, 109, 142], [46, 110, 142], [46, 111, 142], [45, 112, 142], [45, 113, 142], [44, 113, 142],
    [44, 114, 142], [44, 115, 142], [43, 116, 142], [43, 117, 142], [42, 118, 142], [42, 119, 142], [42, 120, 142], [41, 121, 142],
    [41, 122, 142], [41, 123, 142], [40, 124, 142], [40, 125, 142], [39, 126, 142], [39, 127, 142], [39, 128, 142], [38, 129, 142],
    [38, 130, 142], [38, 130, 142], [37, 131, 142], [37, 132, 142], [37, 133, 142], [36, 134, 142], [36, 135, 142], [35, 136, 142],
    [35, 137, 142], [35, 138, 141], [34, 139, 141], [34, 140, 141], [34, 141, 141], [33, 142, 141], [33, 143, 141], [33, 144, 141],
    [33, 145, 140], [32, 146, 140], [32, 146, 140], [32, 147, 140], [31, 148, 140], [31, 149, 139], [31, 150, 139], [31, 151, 139],
    [31, 152, 139], [31, 153, 138], [31, 154, 138], [30, 155, 138], [30, 156, 137], [30, 157, 137], [31, 158, 137], [31, 159, 136],
    [31, 160, 136], [31, 161, 136], [31, 161, 135], [31, 162, 135], [32, 163, 134], [32, 164, 134], [33, 165, 133], [33, 166, 133],
    [34, 167, 133], [34, 168, 132], [35, 169, 131], [36, 170, 131], [37, 171, 130], [37, 172, 130], [38, 173, 129], [39, 173, 129],
    [40, 174, 128], [41, 175, 127], [42, 176, 127], [44, 177, 126], [45, 178, 125], [46, 179, 124], [47, 180, 124], [49, 181, 123],
    [50, 182, 122], [52, 182, 121], [53, 183, 121], [55, 184, 120], [56, 185, 119], [58, 186, 118], [59, 187, 117], [61, 188, 116],
    [63, 188, 115], [64, 189, 114], [66, 190, 113], [68, 191, 112], [70, 192, 111], [72, 193, 110], [74, 193, 109], [76, 194, 108],
    [78, 195, 107], [80, 196, 106], [82, 197, 105], [84, 197, 104], [86, 198, 103], [88, 199, 101], [90, 200, 100], [92, 200, 99],
    [94, 201, 98], [96, 202, 96], [99, 203, 95], [101, 203, 94], [103, 204, 92], [105, 205, 91], [108, 205, 90], [110, 206, 88],
    [112, 207, 87], [115, 208, 86], [117, 208, 84], [119, 209, 83], [122, 209, 81], [124, 210, 80], [127, 211, 78], [129, 211, 77],
    [132, 212, 75], [134, 213, 73], [137, 213, 72], [139, 214, 70], [142, 214, 69], [144, 215, 67], [147, 215, 65], [149, 216, 64],
    [152, 216, 62], [155, 217, 60], [157, 217, 59], [160, 218, 57], [162, 218, 55], [165, 219, 54], [168, 219, 52], [170, 220, 50],
    [173, 220, 48], [176, 221, 47], [178, 221, 45], [181, 222, 43], [184, 222, 41], [186, 222, 40], [189, 223, 38], [192, 223, 37],
    [194, 223, 35], [197, 224, 33], [200, 224, 32], [202, 225, 31], [205, 225, 29], [208, 225, 28], [210, 226, 27], [213, 226, 26],
    [216, 226, 25], [218, 227, 25], [221, 227, 24], [223, 227, 24], [226, 228, 24], [229, 228, 25], [231, 228, 25], [234, 229, 26],
    [236, 229, 27], [239, 229, 28], [241, 229, 29], [244, 230, 30], [246, 230, 32], [248, 230, 33], [251, 231, 35], [253, 231, 37],
];

/// The viridis colour of `t ∈ [0, 1]` (dark blue-purple at 0, teal at ½, yellow at 1), as
/// 8-bit RGB: the nearest of the 256 tabulated entries. `t` outside `[0, 1]` is clamped; NaN
/// gives [`NAN_COLOR`].
pub fn viridis(t: f64) -> [u8; 3] {
    if t.is_nan() {
        return NAN_COLOR;
    }
    let k = (t.clamp(0.0, 1.0) * 255.0).round() as usize;
    VIRIDIS[k.min(255)]
}

/// The colour of value `v` on the scale `[vmin, vmax]`: `viridis((v − vmin)/(vmax − vmin))`,
/// clipped to the ends of the map; NaN is [`NAN_COLOR`].
fn scale_color(v: f64, vmin: f64, vmax: f64) -> RGBColor {
    let [r, g, b] = if v.is_nan() { NAN_COLOR } else { viridis((v - vmin) / (vmax - vmin)) };
    RGBColor(r, g, b)
}

// ---------------------------------------------------------------------------------------------
// Shared helpers
// ---------------------------------------------------------------------------------------------

type DrawResult<T> = Result<T, Box<dyn std::error::Error>>;

const TITLE_FONT: f64 = 20.0;
const LABEL_FONT: f64 = 16.0;
const TICK_FONT: f64 = 13.0;

/// Registers the bundled font with plotters once per process (its own text layout is
/// not used for drawing, see [`Canvas`], but the font must exist for plotters' styles).
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

/// Strips trailing zeros (and a trailing point) from a decimal number's text.
fn trim_zeros(s: &str) -> String {
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s.to_string()
    }
}

/// Scientific notation with at most four significant digits: `1.5e-4`.
fn fmt_sci(v: f64) -> String {
    let s = format!("{v:.3e}");
    match s.split_once('e') {
        Some((m, e)) => format!("{}e{e}", trim_zeros(m)),
        None => s,
    }
}

/// Tick text on a linear axis spanning `span`: decimals fixed by the span (so that all
/// ticks of an axis read alike), values within `10⁻⁹·span` of zero written `0`, scientific
/// notation for magnitudes `≥ 10⁵` or `< 10⁻³`.
fn fmt_linear_tick(v: f64, span: f64) -> String {
    if v.abs() <= 1e-9 * span {
        return "0".to_string();
    }
    let a = v.abs();
    if !(1e-3..1e5).contains(&a) {
        return fmt_sci(v);
    }
    let decimals = (2 - span.log10().floor() as i32).clamp(0, 10) as usize;
    trim_zeros(&format!("{v:.decimals$}"))
}

/// Tick text on a logarithmic axis: four significant digits, scientific notation for
/// magnitudes `≥ 10⁵` or `< 10⁻³`.
fn fmt_log_tick(v: f64) -> String {
    let a = v.abs();
    if a == 0.0 || !(1e-3..1e5).contains(&a) {
        return fmt_sci(v);
    }
    let decimals = (3 - a.log10().floor() as i32).clamp(0, 10) as usize;
    trim_zeros(&format!("{v:.decimals$}"))
}

// ---------------------------------------------------------------------------------------------
// Field images
// ---------------------------------------------------------------------------------------------

/// A scalar field on a 2-D grid of nodes, to be drawn as a heat map by [`write_field_png`]
/// or [`write_field_svg`].
///
/// Node `(i, j)`, `0 ≤ i < nx`, `0 ≤ j < ny`, is `values[j·nx + i]` (row-major, `x`
/// fastest; row `j` is the vertical index, `j = 0` at the bottom). It is drawn as the cell
/// `[x0 + i·Δx, x0 + (i+1)·Δx] × [y0 + j·Δy, y0 + (j+1)·Δy]` with `Δx = (x1 − x0)/nx`,
/// `Δy = (y1 − y0)/ny`: the extent gives the outer edges of the image, not the node
/// positions (for lattice nodes at integer positions `0 … n−1`, an extent `(−½, n − ½)`
/// puts tick values on the nodes).
///
/// Colours: viridis over `[vmin, vmax]`. Values outside are clipped **in colour only** (a
/// value below `vmin` has the colour of `vmin`, above `vmax` that of `vmax`, including
/// `±∞`); NaN is drawn in grey ([`NAN_COLOR`]), for nodes a caller masks (inside solids).
///
/// For the paper's Figures 3 and 4: `values = |u| / v_tip` on the vertical plane through the
/// impeller axis (`v_tip = π N D`, impeller speed `N` in rev per time step and diameter `D`
/// in lattice spacings), extent in lattice units or scaled by the tank diameter `T`,
/// `vmin = 0`, `vmax = 1`, and the particles cut by the plane outlined with
/// [`cylinder_section`] (in the extent's units).
///
/// Outlines: closed polygons drawn over the map as thin (1 pixel) white lines, clipped to
/// the extent; a polygon's last vertex is joined to its first. Vertices with a non-finite
/// coordinate break the line there.
#[derive(Clone, Debug)]
pub struct FieldImage<'a> {
    /// Node values, row-major (`values[j·nx + i]`), `nx·ny` of them.
    pub values: &'a [f64],
    /// Nodes along the horizontal axis.
    pub nx: usize,
    /// Nodes along the vertical axis.
    pub ny: usize,
    /// Outer edges of the image `(x0, x1, y0, y1)` in the axes' units (lattice or physical);
    /// `x0 < x1`, `y0 < y1`, finite. The map keeps this extent's aspect ratio.
    pub extent: (f64, f64, f64, f64),
    /// Value drawn with the low end of the colour map.
    pub vmin: f64,
    /// Value drawn with the high end of the colour map (`vmax > vmin`).
    pub vmax: f64,
    /// Title above the figure (empty: none).
    pub title: &'a str,
    /// Label beside the colour bar, e.g. `"|u| / v_tip"` (empty: none).
    pub colorbar_label: &'a str,
    /// Label of the horizontal axis (empty: none).
    pub x_label: &'a str,
    /// Label of the vertical axis (empty: none).
    pub y_label: &'a str,
    /// Closed polygons `[(x, y), …]` in the extent's coordinates, outlined over the map
    /// (for instance the particles' sections by the plane); `&[]` for none.
    pub outlines: &'a [Vec<(f64, f64)>],
}

/// How large the map of a [`FieldImage`] is drawn (the coloured area alone; axes, title and
/// colour bar are added around it). The map's height follows from its width and the
/// extent's aspect ratio, `h = w·(y1 − y0)/(x1 − x0)`, rounded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FieldSize {
    /// `n` pixels per node along x: the map is `nx·n` pixels wide (and `ny·n` high when the
    /// cells are square).
    PixelsPerNode(u32),
    /// The map is this many pixels wide.
    MapWidth(u32),
}

// Field figure layout, in pixels.
const FIELD_OUTER: u32 = 12;
const FIELD_LEFT: u32 = 80;
const FIELD_BOTTOM: u32 = 58;
const FIELD_GAP: u32 = 24;
const BAR_WIDTH: u32 = 22;
const BAR_LABELS: u32 = 90;

fn field_title_height(title: &str) -> u32 {
    if title.is_empty() {
        14
    } else {
        44
    }
}

/// Writes `img` as a PNG heat map: the field in viridis with ticked axes, equal aspect
/// ratio of the extent, the outlines, a colour bar with ticks on the right, and the title
/// on top. The file is written atomically. Errors ([`PlotError::Input`]) for
/// `values.len() ≠ nx·ny`, an empty grid, a non-finite or empty extent or colour range
/// (`vmin ≥ vmax`), a size of zero, or a figure larger than [`MAX_SIDE`] pixels on a side.
pub fn write_field_png(path: &Path, img: &FieldImage, size: FieldSize) -> Result<(), PlotError> {
    let bad = |reason: String| PlotError::Input { path: path.to_path_buf(), reason };
    let (mw, mh) = check_field(img, size).map_err(bad)?;
    let (w, h) = field_figure_size(img, mw, mh);
    let rgb = guarded(path, || {
        let mut buf = vec![255u8; w as usize * h as usize * 3];
        {
            let root = Canvas(BitMapBackend::with_buffer(&mut buf, (w, h))).into_drawing_area();
            draw_field(&root, img, mw, mh)?;
            root.present()?;
        }
        Ok(buf)
    })?;
    write_png(path, &rgb, w, h)
}

/// Writes `img` as an SVG heat map, laid out exactly as [`write_field_png`] lays out the PNG
/// of the same `size` (one SVG user unit per PNG pixel): axes, ticks, labels, frames and
/// outlines as vector elements, text as `<text>`, the map and the colour bar as embedded PNG
/// images of exactly the PNG's pixels (not one element per node). The file is written
/// atomically; errors as for [`write_field_png`].
pub fn write_field_svg(path: &Path, img: &FieldImage, size: FieldSize) -> Result<(), PlotError> {
    let bad = |reason: String| PlotError::Input { path: path.to_path_buf(), reason };
    let (mw, mh) = check_field(img, size).map_err(bad)?;
    let (w, h) = field_figure_size(img, mw, mh);
    let doc = guarded(path, || {
        let mut doc = String::new();
        {
            let root = SvgCanvas::new(&mut doc, (w, h)).into_drawing_area();
            draw_field(&root, img, mw, mh)?;
            root.present()?;
        }
        Ok(doc)
    })?;
    write_bytes(path, doc.as_bytes())
}

/// Validates a field image and returns the map's size in pixels.
fn check_field(img: &FieldImage, size: FieldSize) -> Result<(u32, u32), String> {
    let (nx, ny) = (img.nx, img.ny);
    if nx == 0 || ny == 0 {
        return Err(format!("empty field: {nx} x {ny} nodes"));
    }
    match nx.checked_mul(ny) {
        Some(n) if n == img.values.len() => {}
        _ => {
            return Err(format!(
                "field has {} values; {nx} x {ny} nodes need {}",
                img.values.len(),
                nx as f64 * ny as f64
            ))
        }
    }
    let (x0, x1, y0, y1) = img.extent;
    if ![x0, x1, y0, y1].iter().all(|v| v.is_finite()) || x0 >= x1 || y0 >= y1 {
        return Err(format!("extent ({x0}, {x1}, {y0}, {y1}) must be finite with x0 < x1 and y0 < y1"));
    }
    if !img.vmin.is_finite() || !img.vmax.is_finite() || img.vmin >= img.vmax {
        return Err(format!(
            "colour range vmin = {}, vmax = {} must be finite with vmin < vmax",
            img.vmin, img.vmax
        ));
    }
    let mw = match size {
        FieldSize::PixelsPerNode(n) => n as f64 * nx as f64,
        FieldSize::MapWidth(w) => w as f64,
    };
    let mh = (mw * (y1 - y0) / (x1 - x0)).round();
    let w = mw + (2 * FIELD_OUTER + FIELD_LEFT + FIELD_GAP + BAR_WIDTH + BAR_LABELS) as f64;
    let h = mh + (field_title_height(img.title) + FIELD_BOTTOM + FIELD_OUTER) as f64;
    if mw < 1.0 || mh < 1.0 {
        return Err(format!("map of {mw} x {mh} pixels is empty (size {size:?})"));
    }
    if w > MAX_SIDE as f64 || h > MAX_SIDE as f64 {
        return Err(format!(
            "figure of {w} x {h} pixels exceeds {MAX_SIDE} pixels on a side (size {size:?})"
        ));
    }
    Ok((mw as u32, mh as u32))
}

/// The size of a field figure, in pixels, whose map is `mw × mh` pixels.
fn field_figure_size(img: &FieldImage, mw: u32, mh: u32) -> (u32, u32) {
    let w = FIELD_OUTER + FIELD_LEFT + mw + FIELD_GAP + BAR_WIDTH + BAR_LABELS + FIELD_OUTER;
    let h = field_title_height(img.title) + mh + FIELD_BOTTOM + FIELD_OUTER;
    (w, h)
}

/// Draws a validated field image with a `mw × mh` pixel map on `root`, which is
/// [`field_figure_size`] large.
fn draw_field<DB>(root: &DrawingArea<DB, Shift>, img: &FieldImage, mw: u32, mh: u32) -> DrawResult<()>
where
    DB: Surface,
    DB::ErrorType: 'static,
{
    let title_h = field_title_height(img.title);
    let map_w = FIELD_LEFT + mw + FIELD_GAP;
    let bar_w = BAR_WIDTH + BAR_LABELS;
    let (w, _) = field_figure_size(img, mw, mh);
    let (x0, x1, y0, y1) = img.extent;
    let (vmin, vmax) = (img.vmin, img.vmax);
    root.fill(&WHITE)?;
    if !img.title.is_empty() {
        let style = font(TITLE_FONT).pos(Pos::new(HPos::Center, VPos::Top));
        root.draw(&Text::new(img.title.to_string(), (w as i32 / 2, 12), style))?;
    }

    // The map.
    let map_area = root.clone().shrink((FIELD_OUTER, title_h), (map_w, mh + FIELD_BOTTOM));
    let mut chart = ChartBuilder::on(&map_area)
        .x_label_area_size(FIELD_BOTTOM)
        .y_label_area_size(FIELD_LEFT)
        .margin_right(FIELD_GAP)
        .build_cartesian_2d(x0..x1, y0..y1)?;
    paint_map(chart.plotting_area(), img)?;
    draw_outlines(&mut chart, img)?;
    let (xspan, yspan) = (x1 - x0, y1 - y0);
    let fx = move |v: &f64| fmt_linear_tick(*v, xspan);
    let fy = move |v: &f64| fmt_linear_tick(*v, yspan);
    chart
        .configure_mesh()
        .disable_mesh()
        .x_labels((mw as usize / 70).clamp(2, 12))
        .y_labels((mh as usize / 50).clamp(2, 12))
        .x_label_formatter(&fx)
        .y_label_formatter(&fy)
        .label_style(font(TICK_FONT))
        .axis_desc_style(font(LABEL_FONT))
        .x_desc(img.x_label)
        .y_desc(img.y_label)
        .draw()?;
    frame(chart.plotting_area())?;

    // The colour bar.
    let bar_area = root.clone().shrink((FIELD_OUTER + map_w, title_h), (bar_w, mh + FIELD_BOTTOM));
    let mut bar = ChartBuilder::on(&bar_area)
        .right_y_label_area_size(BAR_LABELS)
        .margin_bottom(FIELD_BOTTOM)
        .build_cartesian_2d(0.0..1.0, vmin..vmax)?;
    paint_bar(bar.plotting_area(), vmin, vmax)?;
    let vspan = vmax - vmin;
    let fv = move |v: &f64| fmt_linear_tick(*v, vspan);
    bar.configure_mesh()
        .disable_mesh()
        .disable_x_axis()
        .y_labels((mh as usize / 40).clamp(2, 12))
        .y_label_formatter(&fv)
        .label_style(font(TICK_FONT))
        .draw()?;
    frame(bar.plotting_area())?;
    if !img.colorbar_label.is_empty() {
        // Read bottom to top, like the y label (plotters would set a right-hand label top
        // to bottom).
        let style =
            font(LABEL_FONT).transform(FontTransform::Rotate270).pos(Pos::new(HPos::Center, VPos::Center));
        let at = ((FIELD_OUTER + map_w + bar_w) as i32 - 14, (title_h + mh / 2) as i32);
        root.draw(&Text::new(img.colorbar_label.to_string(), at, style))?;
    }
    Ok(())
}

type Plane<DB> = DrawingArea<DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// Colours every pixel of the plotting area with the node whose cell holds the pixel's
/// centre (the nodes as a raster of `nx × ny` cells).
fn paint_map<DB>(area: &Plane<DB>, img: &FieldImage) -> DrawResult<()>
where
    DB: Surface,
    DB::ErrorType: 'static,
{
    // Raster rows run top to bottom; node rows bottom to top.
    let raster = Raster::from_fn(img.nx, img.ny, |i, r| {
        scale_color(img.values[(img.ny - 1 - r) * img.nx + i], img.vmin, img.vmax)
    });
    paint_raster(area, raster)
}

/// Fills the colour bar's plotting area: each pixel row with the colour of the value at its
/// centre.
fn paint_bar<DB>(area: &Plane<DB>, vmin: f64, vmax: f64) -> DrawResult<()>
where
    DB: Surface,
    DB::ErrorType: 'static,
{
    let ph = area.get_pixel_range().1.len();
    let raster = Raster::from_fn(1, ph, |_, py| {
        scale_color(vmax - (py as f64 + 0.5) / ph as f64 * (vmax - vmin), vmin, vmax)
    });
    paint_raster(area, raster)
}

/// Draws the field image's outlines on the map, clipped to the extent.
fn draw_outlines<DB>(
    chart: &mut ChartContext<'_, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>,
    img: &FieldImage,
) -> DrawResult<()>
where
    DB: Surface,
    DB::ErrorType: 'static,
{
    let (x0, x1, y0, y1) = img.extent;
    let linear = Axis { log: false };
    let line = WHITE.stroke_width(1);
    for polygon in img.outlines {
        let Some(&first) = polygon.first() else { continue };
        let mut closed = polygon.clone();
        closed.push(first);
        let ring = Series::new("", closed, SeriesStyle::Line);
        for l in pieces(&ring, linear, linear, (x0, x1), (y0, y1)).lines {
            chart.draw_series(std::iter::once(PathElement::new(l, line)))?;
        }
    }
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

// ---------------------------------------------------------------------------------------------
// Line plots
// ---------------------------------------------------------------------------------------------

/// How a [`Series`] is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum SeriesStyle {
    /// A polyline through the points (2 px wide).
    #[default]
    Line,
    /// A filled circle at each point.
    Points,
    /// Both.
    LinePoints,
}

/// One x–y data set of a [`LinePlot`].
///
/// Points with a non-finite coordinate (or a non-positive one on a logarithmic axis) are
/// gaps: a line is broken there and no marker is drawn. Lines are clipped to the plot's
/// ranges; markers outside them are left out.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Series {
    /// Legend text; a series with an empty label is left out of the legend.
    pub label: String,
    /// The points `(x, y)`, in drawing order.
    pub points: Vec<(f64, f64)>,
    /// Line, markers, or both.
    pub style: SeriesStyle,
}

impl Series {
    /// A series from its parts.
    pub fn new(label: impl Into<String>, points: Vec<(f64, f64)>, style: SeriesStyle) -> Self {
        Series { label: label.into(), points, style }
    }
}

/// Where the legend of a [`LinePlot`] sits inside the plotting area.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum LegendPosition {
    /// Upper right corner.
    #[default]
    UpperRight,
    /// Upper left corner.
    UpperLeft,
    /// Lower right corner.
    LowerRight,
    /// Lower left corner.
    LowerLeft,
    /// No legend.
    Hidden,
}

/// An x–y plot of one or more [`Series`], drawn by [`write_line_png`] or [`write_line_svg`].
/// Series get distinct colours in order (matplotlib's "tab10" cycle).
///
/// Ranges: `None` takes the range of the drawable points plus 4 % on each side (in decades
/// on a logarithmic axis; a single value gets ±5 %, or ±1 at zero, or ±½ decade). A given
/// range must be finite with `lo < hi`, and positive on a logarithmic axis.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct LinePlot {
    /// Title above the plot (empty: none).
    pub title: String,
    /// Label of the x axis, with units, e.g. `"t N (revolutions)"`.
    pub x_label: String,
    /// Label of the y axis, e.g. `"Np = P / (ρ N³ D⁵)"`.
    pub y_label: String,
    /// The data sets.
    pub series: Vec<Series>,
    /// Fixed x range `(lo, hi)`, or `None` for automatic.
    pub x_range: Option<(f64, f64)>,
    /// Fixed y range `(lo, hi)`, or `None` for automatic.
    pub y_range: Option<(f64, f64)>,
    /// Logarithmic x axis (base 10).
    pub log_x: bool,
    /// Logarithmic y axis (base 10).
    pub log_y: bool,
    /// Legend placement.
    pub legend: LegendPosition,
}

/// Smallest width or height of a line plot, in pixels.
pub const MIN_LINE_SIDE: u32 = 120;

/// The "tab10" colour cycle.
const PALETTE: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

/// Writes `plot` as a `width × height` PNG: axes with ticks and labels, one colour per
/// series, a legend of the labelled series, the title on top. The file is written
/// atomically. Errors ([`PlotError::Input`]) for no series, no drawable point at all, a bad
/// fixed range, or a size outside [`MIN_LINE_SIDE`]`..=`[`MAX_SIDE`].
pub fn write_line_png(path: &Path, plot: &LinePlot, width: u32, height: u32) -> Result<(), PlotError> {
    let bad = |reason: String| PlotError::Input { path: path.to_path_buf(), reason };
    let (xr, yr) = check_lines(plot, width, height).map_err(bad)?;
    let rgb = guarded(path, || {
        let mut buf = vec![255u8; width as usize * height as usize * 3];
        {
            let root = Canvas(BitMapBackend::with_buffer(&mut buf, (width, height))).into_drawing_area();
            draw_lines(&root, plot, xr, yr)?;
            root.present()?;
        }
        Ok(buf)
    })?;
    write_png(path, &rgb, width, height)
}

/// Writes `plot` as a `width × height` SVG (user units, one per PNG pixel), laid out exactly
/// as [`write_line_png`] lays out the PNG: axes, grid, series, markers and legend as vector
/// elements, text as `<text>`. The file is written atomically; errors as for
/// [`write_line_png`].
pub fn write_line_svg(path: &Path, plot: &LinePlot, width: u32, height: u32) -> Result<(), PlotError> {
    let bad = |reason: String| PlotError::Input { path: path.to_path_buf(), reason };
    let (xr, yr) = check_lines(plot, width, height).map_err(bad)?;
    let doc = guarded(path, || {
        let mut doc = String::new();
        {
            let root = SvgCanvas::new(&mut doc, (width, height)).into_drawing_area();
            draw_lines(&root, plot, xr, yr)?;
            root.present()?;
        }
        Ok(doc)
    })?;
    write_bytes(path, doc.as_bytes())
}

/// One axis' mapping into "axis space": `log10` on a logarithmic axis, identity otherwise.
#[derive(Clone, Copy)]
struct Axis {
    log: bool,
}

impl Axis {
    /// The value in axis space, or `None` if it cannot be drawn on this axis.
    fn fwd(self, v: f64) -> Option<f64> {
        let a = if self.log { v.log10() } else { v };
        a.is_finite().then_some(a)
    }
    fn inv(self, a: f64) -> f64 {
        if self.log {
            10f64.powf(a)
        } else {
            a
        }
    }
}

/// A closed interval `(lo, hi)` on one axis.
type Interval = (f64, f64);

/// Validates a line plot; returns its x and y ranges in data units.
fn check_lines(plot: &LinePlot, width: u32, height: u32) -> Result<(Interval, Interval), String> {
    if !(MIN_LINE_SIDE..=MAX_SIDE).contains(&width) || !(MIN_LINE_SIDE..=MAX_SIDE).contains(&height) {
        return Err(format!(
            "size {width} x {height} pixels is outside {MIN_LINE_SIDE}..={MAX_SIDE} on a side"
        ));
    }
    if plot.series.is_empty() {
        return Err("no series".to_string());
    }
    let (ax, ay) = (Axis { log: plot.log_x }, Axis { log: plot.log_y });
    let drawable: Vec<(f64, f64)> = plot
        .series
        .iter()
        .flat_map(|s| s.points.iter())
        .filter_map(|&(x, y)| Some((ax.fwd(x)?, ay.fwd(y)?)))
        .collect();
    if drawable.is_empty() {
        let n: usize = plot.series.iter().map(|s| s.points.len()).sum();
        return Err(if n == 0 {
            "no data: every series is empty".to_string()
        } else {
            format!("none of the {n} points is drawable (non-finite, or non-positive on a log axis)")
        });
    }
    let range = |name: &str, given: Option<(f64, f64)>, axis: Axis, vals: &mut dyn Iterator<Item = f64>| {
        match given {
            Some((lo, hi)) => {
                if !lo.is_finite() || !hi.is_finite() || lo >= hi {
                    Err(format!("{name} range ({lo}, {hi}) must be finite with lo < hi"))
                } else if axis.log && lo <= 0.0 {
                    Err(format!("{name} range ({lo}, {hi}) must be positive on a logarithmic axis"))
                } else {
                    Ok((lo, hi))
                }
            }
            None => {
                let (lo, hi) =
                    vals.fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| (l.min(v), h.max(v)));
                let (lo, hi) = if hi > lo {
                    let pad = 0.04 * (hi - lo);
                    (lo - pad, hi + pad)
                } else if axis.log {
                    (lo - 0.5, hi + 0.5)
                } else if lo == 0.0 {
                    (-1.0, 1.0)
                } else {
                    (lo - 0.05 * lo.abs(), hi + 0.05 * hi.abs())
                };
                let (lo, hi) = (axis.inv(lo), axis.inv(hi));
                if lo.is_finite() && hi.is_finite() && lo < hi {
                    Ok((lo, hi))
                } else {
                    Err(format!("automatic {name} range ({lo}, {hi}) is unusable; give {name}_range"))
                }
            }
        }
    };
    let xr = range("x", plot.x_range, ax, &mut drawable.iter().map(|p| p.0))?;
    let yr = range("y", plot.y_range, ay, &mut drawable.iter().map(|p| p.1))?;
    Ok((xr, yr))
}

/// Liang–Barsky: the part of the segment `p → q` inside the box `[x0, x1] × [y0, y1]`.
fn clip_segment(
    p: (f64, f64),
    q: (f64, f64),
    bx: (f64, f64),
    by: (f64, f64),
) -> Option<((f64, f64), (f64, f64))> {
    let (dx, dy) = (q.0 - p.0, q.1 - p.1);
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for (den, num) in [(-dx, p.0 - bx.0), (dx, bx.1 - p.0), (-dy, p.1 - by.0), (dy, by.1 - p.1)] {
        if den == 0.0 {
            if num < 0.0 {
                return None;
            }
        } else {
            let t = num / den;
            if den < 0.0 {
                t0 = t0.max(t);
            } else {
                t1 = t1.min(t);
            }
        }
    }
    (t0 <= t1).then_some(((p.0 + t0 * dx, p.1 + t0 * dy), (p.0 + t1 * dx, p.1 + t1 * dy)))
}

/// The drawable pieces of a series: polylines (split at gaps, clipped to the ranges) and
/// markers inside the ranges, in data units.
struct Pieces {
    lines: Vec<Vec<(f64, f64)>>,
    markers: Vec<(f64, f64)>,
}

fn pieces(s: &Series, ax: Axis, ay: Axis, xr: (f64, f64), yr: (f64, f64)) -> Pieces {
    // Work in axis space, where lines are straight.
    let bx = (ax.fwd(xr.0).unwrap_or(f64::NEG_INFINITY), ax.fwd(xr.1).unwrap_or(f64::INFINITY));
    let by = (ay.fwd(yr.0).unwrap_or(f64::NEG_INFINITY), ay.fwd(yr.1).unwrap_or(f64::INFINITY));
    let to_data = |a: (f64, f64)| (ax.inv(a.0), ay.inv(a.1));
    let pts: Vec<Option<(f64, f64)>> =
        s.points.iter().map(|&(x, y)| Some((ax.fwd(x)?, ay.fwd(y)?))).collect();
    let mut lines = Vec::new();
    if s.style != SeriesStyle::Points {
        let mut cur: Vec<(f64, f64)> = Vec::new();
        for w in pts.windows(2) {
            match (w[0], w[1]) {
                (Some(p), Some(q)) => match clip_segment(p, q, bx, by) {
                    Some((a, b)) => {
                        let a = to_data(a);
                        if cur.last() != Some(&a) {
                            if cur.len() > 1 {
                                lines.push(std::mem::take(&mut cur));
                            }
                            cur.clear();
                            cur.push(a);
                        }
                        cur.push(to_data(b));
                    }
                    None => {
                        if cur.len() > 1 {
                            lines.push(std::mem::take(&mut cur));
                        }
                        cur.clear();
                    }
                },
                _ => {
                    if cur.len() > 1 {
                        lines.push(std::mem::take(&mut cur));
                    }
                    cur.clear();
                }
            }
        }
        if cur.len() > 1 {
            lines.push(cur);
        }
    }
    let mut markers = Vec::new();
    if s.style != SeriesStyle::Line {
        let inside = |v: f64, b: (f64, f64)| v >= b.0 && v <= b.1;
        markers = pts
            .iter()
            .flatten()
            .filter(|p| inside(p.0, bx) && inside(p.1, by))
            .map(|&p| to_data(p))
            .collect();
    }
    Pieces { lines, markers }
}

/// Draws a validated line plot on `root` (the whole figure).
fn draw_lines<DB>(
    root: &DrawingArea<DB, Shift>,
    plot: &LinePlot,
    xr: Interval,
    yr: Interval,
) -> DrawResult<()>
where
    DB: DrawingBackend,
    DB::ErrorType: 'static,
{
    root.fill(&WHITE)?;
    let (x, y) = (xr.0..xr.1, yr.0..yr.1);
    match (plot.log_x, plot.log_y) {
        (false, false) => draw_chart(root, plot, x, y, xr, yr),
        (true, false) => draw_chart(root, plot, x.log_scale(), y, xr, yr),
        (false, true) => draw_chart(root, plot, x, y.log_scale(), xr, yr),
        (true, true) => draw_chart(root, plot, x.log_scale(), y.log_scale(), xr, yr),
    }
}

/// Draws the chart on either kind of axes.
fn draw_chart<DB, XS, YS>(
    root: &DrawingArea<DB, Shift>,
    plot: &LinePlot,
    xs: XS,
    ys: YS,
    xr: (f64, f64),
    yr: (f64, f64),
) -> DrawResult<()>
where
    DB: DrawingBackend,
    DB::ErrorType: 'static,
    XS: AsRangedCoord<Value = f64>,
    YS: AsRangedCoord<Value = f64>,
    XS::CoordDescType: ValueFormatter<f64>,
    YS::CoordDescType: ValueFormatter<f64>,
{
    let (w, h) = root.dim_in_pixel();
    let mut builder = ChartBuilder::on(root);
    builder.margin(16).x_label_area_size(56).y_label_area_size(84);
    if !plot.title.is_empty() {
        builder.caption(&plot.title, font(TITLE_FONT));
    }
    let mut chart = builder.build_cartesian_2d(xs, ys)?;

    let (xspan, yspan) = (xr.1 - xr.0, yr.1 - yr.0);
    let (log_x, log_y) = (plot.log_x, plot.log_y);
    let fx = move |v: &f64| if log_x { fmt_log_tick(*v) } else { fmt_linear_tick(*v, xspan) };
    let fy = move |v: &f64| if log_y { fmt_log_tick(*v) } else { fmt_linear_tick(*v, yspan) };
    chart
        .configure_mesh()
        .x_labels((w as usize / 90).clamp(3, 14))
        .y_labels((h as usize / 60).clamp(3, 14))
        .x_label_formatter(&fx)
        .y_label_formatter(&fy)
        .label_style(font(TICK_FONT))
        .axis_desc_style(font(LABEL_FONT))
        .x_desc(plot.x_label.as_str())
        .y_desc(plot.y_label.as_str())
        .light_line_style(RGBColor(235, 235, 235))
        .bold_line_style(RGBColor(210, 210, 210))
        .draw()?;

    let (ax, ay) = (Axis { log: plot.log_x }, Axis { log: plot.log_y });
    let mut any_label = false;
    for (k, s) in plot.series.iter().enumerate() {
        let color = PALETTE[k % PALETTE.len()];
        let line = color.stroke_width(2);
        let dot = color.filled();
        let p = pieces(s, ax, ay, xr, yr);
        for l in p.lines {
            chart.draw_series(std::iter::once(PathElement::new(l, line)))?;
        }
        chart.draw_series(p.markers.into_iter().map(|q| Circle::new(q, 3, dot)))?;
        if !s.label.is_empty() {
            any_label = true;
            // An empty series carries the legend entry.
            let entry = chart.draw_series(std::iter::empty::<PathElement<(f64, f64)>>())?;
            entry.label(s.label.as_str());
            match s.style {
                SeriesStyle::Line => {
                    entry.legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], line));
                }
                SeriesStyle::Points => {
                    entry.legend(move |(x, y)| Circle::new((x + 12, y), 3, dot));
                }
                SeriesStyle::LinePoints => {
                    entry.legend(move |(x, y)| {
                        EmptyElement::at((x, y))
                            + PathElement::new(vec![(0, 0), (24, 0)], line)
                            + Circle::new((12, 0), 3, dot)
                    });
                }
            }
        }
    }
    let position = match plot.legend {
        LegendPosition::UpperRight => SeriesLabelPosition::UpperRight,
        LegendPosition::UpperLeft => SeriesLabelPosition::UpperLeft,
        LegendPosition::LowerRight => SeriesLabelPosition::LowerRight,
        LegendPosition::LowerLeft => SeriesLabelPosition::LowerLeft,
        LegendPosition::Hidden => return Ok(()),
    };
    if any_label {
        chart
            .configure_series_labels()
            .position(position)
            .margin(10)
            .label_font(font(TICK_FONT))
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(160, 160, 160))
            .draw()?;
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Text setting
// ---------------------------------------------------------------------------------------------

/// A bitmap backend that sets text itself ([`Canvas`]).
mod canvas {
    use std::io;
    use std::sync::OnceLock;

    use ab_glyph::{Font, FontRef, PxScale, ScaleFont};
    use plotters::prelude::BitMapBackend;
    use plotters::style::text_anchor::{HPos, VPos};
    use plotters_backend::{
        BackendColor, BackendCoord, BackendStyle, BackendTextStyle, DrawingBackend, DrawingErrorKind,
    };

    use super::FONT_BYTES;

    /// The bundled font, parsed once; `None` if the bytes cannot be parsed (never, in practice).
    pub(super) fn bundled_font() -> Option<&'static FontRef<'static>> {
        static FONT: OnceLock<Option<FontRef<'static>>> = OnceLock::new();
        FONT.get_or_init(|| FontRef::try_from_slice(FONT_BYTES).ok()).as_ref()
    }

    /// How a text is set with the bundled font at `size` pixels, for backends that place the
    /// text box themselves (the SVG's `<text>` elements).
    pub(super) struct TextMetrics {
        /// The box: `(advance width, ascent − descent)` in whole pixels, as [`Canvas`] sets it.
        pub(super) size: (i32, i32),
        /// Baseline below the box's top edge, in pixels.
        pub(super) ascent: f64,
        /// The CSS `font-size` (the em) that gives this font the height `size`: ab_glyph's
        /// pixel scale is the height ascent − descent, CSS sizes the em.
        pub(super) em: f64,
    }

    /// The [`TextMetrics`] of `text` at `size` pixels; `None` if the font cannot be parsed.
    pub(super) fn text_metrics(size: f64, text: &str) -> Option<TextMetrics> {
        let font = bundled_font()?;
        let scaled = font.as_scaled(PxScale::from(size as f32));
        let em = match font.units_per_em() {
            Some(upem) if font.height_unscaled() > 0.0 => {
                size * f64::from(upem) / f64::from(font.height_unscaled())
            }
            _ => size,
        };
        Some(TextMetrics { size: text_box(font, size, text), ascent: f64::from(scaled.ascent()), em })
    }

    /// The box of `text` set at `size` pixels (ascent − descent): `(advance width, size)`.
    fn text_box(font: &FontRef<'static>, size: f64, text: &str) -> (i32, i32) {
        let f = font.as_scaled(PxScale::from(size as f32));
        let mut caret = 0.0f32;
        let mut prev = None;
        for c in text.chars() {
            let id = f.glyph_id(c);
            if let Some(p) = prev {
                caret += f.kern(p, id);
            }
            caret += f.h_advance(id);
            prev = Some(id);
        }
        (caret.ceil() as i32, (f.ascent() - f.descent()).ceil() as i32)
    }

    /// Rasterises `text` at `size` pixels into its box (top left `(0, 0)`, baseline at the
    /// ascent): `put(x, y, coverage)` for every covered pixel.
    fn set_text(font: &FontRef<'static>, size: f64, text: &str, mut put: impl FnMut(i32, i32, f32)) {
        let f = font.as_scaled(PxScale::from(size as f32));
        let mut caret = 0.0f32;
        let mut prev = None;
        for c in text.chars() {
            let id = f.glyph_id(c);
            if let Some(p) = prev {
                caret += f.kern(p, id);
            }
            let glyph = id.with_scale_and_position(f.scale(), ab_glyph::point(caret, f.ascent()));
            if let Some(outline) = f.outline_glyph(glyph) {
                let b = outline.px_bounds();
                let (x0, y0) = (b.min.x as i32, b.min.y as i32);
                outline.draw(|gx, gy, cov| put(x0 + gx as i32, y0 + gy as i32, cov));
            }
            caret += f.h_advance(id);
            prev = Some(id);
        }
    }

    /// The bitmap backend with its own text setting.
    ///
    /// plotters' `ab_glyph` text path drops each glyph's left side bearing, so that digits stand
    /// apart unevenly ("1 00"). This wrapper hands all drawing to the bitmap backend except
    /// text, which it sets with the bundled font (whatever family the style names): glyphs at
    /// their advances, kerning and bearings, in a box `advance width × size` with the baseline
    /// at the font's ascent, anchored and rotated as the style asks, blended by coverage.
    pub(super) struct Canvas<'a>(pub(super) BitMapBackend<'a>);

    type CanvasResult = Result<(), DrawingErrorKind<<BitMapBackend<'static> as DrawingBackend>::ErrorType>>;

    impl<'a> DrawingBackend for Canvas<'a> {
        type ErrorType = <BitMapBackend<'a> as DrawingBackend>::ErrorType;

        fn get_size(&self) -> (u32, u32) {
            self.0.get_size()
        }
        fn ensure_prepared(&mut self) -> CanvasResult {
            self.0.ensure_prepared()
        }
        fn present(&mut self) -> CanvasResult {
            self.0.present()
        }
        fn draw_pixel(&mut self, point: BackendCoord, color: BackendColor) -> CanvasResult {
            self.0.draw_pixel(point, color)
        }
        fn draw_line<S: BackendStyle>(
            &mut self,
            from: BackendCoord,
            to: BackendCoord,
            style: &S,
        ) -> CanvasResult {
            let color = style.color();
            if style.stroke_width() != 1 || color.alpha == 0.0 {
                return self.0.draw_line(from, to, style);
            }
            if from.0 == to.0 || from.1 == to.1 {
                // The bitmap's fast path for these fills the box from `from` to `to`, which
                // is empty when `to` lies left of or above `from`.
                let (a, b) = if (from.0, from.1) <= (to.0, to.1) { (from, to) } else { (to, from) };
                return self.0.draw_line(a, b, style);
            }
            // A slanted one-pixel line: plotters' rasteriser spreads it over two rows of partly
            // blended pixels, which reads as dots along an outline of many short segments;
            // set whole pixels with Bresenham's algorithm instead, within the canvas.
            let (w, h) = self.0.get_size();
            let f = |p: BackendCoord| (f64::from(p.0), f64::from(p.1));
            let Some((a, b)) =
                super::clip_segment(f(from), f(to), (0.0, f64::from(w) - 1.0), (0.0, f64::from(h) - 1.0))
            else {
                return Ok(());
            };
            let ((mut x, mut y), end) =
                ((a.0.round() as i32, a.1.round() as i32), (b.0.round() as i32, b.1.round() as i32));
            let (dx, dy) = ((end.0 - x).abs(), -(end.1 - y).abs());
            let (sx, sy) = ((end.0 - x).signum(), (end.1 - y).signum());
            let mut err = dx + dy;
            loop {
                self.0.draw_pixel((x, y), color)?;
                if (x, y) == end {
                    return Ok(());
                }
                let e2 = 2 * err;
                if e2 >= dy {
                    err += dy;
                    x += sx;
                }
                if e2 <= dx {
                    err += dx;
                    y += sy;
                }
            }
        }
        fn draw_rect<S: BackendStyle>(
            &mut self,
            upper_left: BackendCoord,
            bottom_right: BackendCoord,
            style: &S,
            fill: bool,
        ) -> CanvasResult {
            self.0.draw_rect(upper_left, bottom_right, style, fill)
        }
        fn draw_path<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
            &mut self,
            path: I,
            style: &S,
        ) -> CanvasResult {
            if style.stroke_width() != 1 {
                return self.0.draw_path(path, style);
            }
            // One-pixel paths segment by segment through this backend's `draw_line`.
            let mut points = path.into_iter();
            let Some(mut from) = points.next() else { return Ok(()) };
            for to in points {
                self.draw_line(from, to, style)?;
                from = to;
            }
            Ok(())
        }
        fn draw_circle<S: BackendStyle>(
            &mut self,
            center: BackendCoord,
            radius: u32,
            style: &S,
            fill: bool,
        ) -> CanvasResult {
            self.0.draw_circle(center, radius, style, fill)
        }
        fn fill_polygon<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
            &mut self,
            vert: I,
            style: &S,
        ) -> CanvasResult {
            self.0.fill_polygon(vert, style)
        }
        fn blit_bitmap(&mut self, pos: BackendCoord, size: (u32, u32), src: &[u8]) -> CanvasResult {
            self.0.blit_bitmap(pos, size, src)
        }

        fn draw_text<S: BackendTextStyle>(
            &mut self,
            text: &str,
            style: &S,
            pos: BackendCoord,
        ) -> CanvasResult {
            let color = style.color();
            if color.alpha == 0.0 {
                return Ok(());
            }
            let font = bundled_font().ok_or_else(font_error)?;
            let (w, h) = text_box(font, style.size(), text);
            let anchor = style.anchor();
            let dx = match anchor.h_pos {
                HPos::Left => 0,
                HPos::Right => -w,
                HPos::Center => -w / 2,
            };
            let dy = match anchor.v_pos {
                VPos::Top => 0,
                VPos::Center => -h / 2,
                VPos::Bottom => -h,
            };
            let transform = style.transform();
            let mut result = Ok(());
            set_text(font, style.size(), text, |x, y, cov| {
                if result.is_ok() && cov > 0.0 {
                    let (x, y) = transform.transform(x + dx, y + dy);
                    let c = BackendColor { alpha: color.alpha * f64::from(cov.min(1.0)), rgb: color.rgb };
                    result = self.0.draw_pixel((pos.0 + x, pos.1 + y), c);
                }
            });
            result
        }

        fn estimate_text_size<S: BackendTextStyle>(
            &self,
            text: &str,
            style: &S,
        ) -> Result<(u32, u32), DrawingErrorKind<Self::ErrorType>> {
            let font = bundled_font().ok_or_else(font_error)?;
            let (w, h) = text_box(font, style.size(), text);
            Ok((w.max(0) as u32, h.max(0) as u32))
        }
    }

    impl super::Surface for Canvas<'_> {
        fn draw_raster(
            &mut self,
            upper_left: BackendCoord,
            size: (u32, u32),
            raster: &super::Raster,
        ) -> CanvasResult {
            self.0.blit_bitmap(upper_left, size, &raster.resample(size.0, size.1))
        }
    }

    pub(super) fn font_error<E: std::error::Error + Send + Sync>() -> DrawingErrorKind<E> {
        DrawingErrorKind::FontError(Box::new(io::Error::other(
            "the bundled font DejaVuSans.ttf could not be parsed",
        )))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Decodes a PNG: (width, height, RGB bytes).
    fn decode(path: &Path) -> (u32, u32, Vec<u8>) {
        let file = std::io::BufReader::new(std::fs::File::open(path).unwrap());
        let mut reader = png::Decoder::new(file).read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut buf).unwrap();
        assert_eq!(info.color_type, png::ColorType::Rgb);
        assert_eq!(info.bit_depth, png::BitDepth::Eight);
        buf.truncate(info.buffer_size());
        (info.width, info.height, buf)
    }

    fn pixel(rgb: &[u8], w: u32, x: u32, y: u32) -> [u8; 3] {
        let k = 3 * (y * w + x) as usize;
        [rgb[k], rgb[k + 1], rgb[k + 2]]
    }

    fn close(a: [u8; 3], b: [u8; 3], tol: i32) -> bool {
        a.iter().zip(b).all(|(&p, q)| (p as i32 - q as i32).abs() <= tol)
    }

    fn field<'a>(values: &'a [f64], nx: usize, ny: usize) -> FieldImage<'a> {
        FieldImage {
            values,
            nx,
            ny,
            extent: (0.0, nx as f64, 0.0, ny as f64),
            vmin: 0.0,
            vmax: 1.0,
            title: "ramp",
            colorbar_label: "|u| / v_tip",
            x_label: "x",
            y_label: "z",
            outlines: &[],
        }
    }

    /// No file and no temporary file is left in `dir`.
    fn assert_empty(dir: &Path) {
        assert_eq!(std::fs::read_dir(dir).unwrap().count(), 0);
    }

    #[test]
    fn viridis_ends_and_nan() {
        assert_eq!(viridis(0.0), [68, 1, 84]);
        assert_eq!(viridis(1.0), [253, 231, 37]);
        assert_eq!(viridis(-3.0), viridis(0.0));
        assert_eq!(viridis(f64::INFINITY), viridis(1.0));
        assert_eq!(viridis(f64::NAN), NAN_COLOR);
        assert!(!VIRIDIS.contains(&NAN_COLOR));
        // Perceptually ordered: luminance rises monotonically along the map.
        let lum = |c: [u8; 3]| 0.2126 * c[0] as f64 + 0.7152 * c[1] as f64 + 0.0722 * c[2] as f64;
        assert!(VIRIDIS.windows(2).all(|w| lum(w[1]) >= lum(w[0]) - 0.5));
    }

    #[test]
    fn ramp_image_runs_dark_to_yellow() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("ramp.png");
        let (nx, ny, ppn) = (50usize, 20usize, 4u32);
        let values: Vec<f64> = (0..nx * ny).map(|k| (k % nx) as f64 / (nx - 1) as f64).collect();
        let img = field(&values, nx, ny);
        write_field_png(&path, &img, FieldSize::PixelsPerNode(ppn)).unwrap();
        let (w, h, rgb) = decode(&path);
        let (mw, mh) = (nx as u32 * ppn, ny as u32 * ppn);
        assert_eq!(w, 2 * FIELD_OUTER + FIELD_LEFT + mw + FIELD_GAP + BAR_WIDTH + BAR_LABELS);
        assert_eq!(h, field_title_height("ramp") + mh + FIELD_BOTTOM + FIELD_OUTER);
        // The map's left and right columns (a few pixels inside the frame).
        let (left, top) = (FIELD_OUTER + FIELD_LEFT, field_title_height("ramp"));
        let y = top + mh / 2;
        let lo = pixel(&rgb, w, left + 3, y);
        let hi = pixel(&rgb, w, left + mw - 4, y);
        assert!(close(lo, viridis(0.0), 2), "left {lo:?}");
        assert!(close(hi, viridis(1.0), 2), "right {hi:?}");
        // Dark purple-blue on the left (blue above red and green), yellow on the right.
        assert!(lo[2] > lo[0] && lo[2] > lo[1], "left {lo:?}");
        assert!(hi[0] > 200 && hi[1] > 200 && hi[2] < 80, "right {hi:?}");
        // Along the ramp the colour follows viridis node by node.
        for i in [10usize, 25, 40] {
            let c = pixel(&rgb, w, left + i as u32 * ppn + ppn / 2, y);
            assert!(close(c, viridis(values[i]), 2), "node {i}: {c:?} vs {:?}", viridis(values[i]));
        }
        // The colour bar: yellow at the top, dark at the bottom.
        let bar_x = FIELD_OUTER + FIELD_LEFT + mw + FIELD_GAP + BAR_WIDTH / 2;
        for row in [3, mh / 2, mh - 4] {
            let t = 1.0 - (row as f64 + 0.5) / mh as f64;
            assert!(close(pixel(&rgb, w, bar_x, top + row), viridis(t), 2), "bar row {row}");
        }
        // Text was drawn: the title band holds dark pixels.
        assert!((0..w).any(|x| pixel(&rgb, w, x, 22).iter().all(|&c| c < 100)));
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn nan_is_grey_and_out_of_range_is_clipped_in_colour() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("mask.png");
        let (nx, ny) = (30usize, 30usize);
        let mut values = vec![0.5; nx * ny];
        for j in 10..20 {
            for i in 10..20 {
                values[j * nx + i] = f64::NAN;
            }
        }
        values[0] = -7.0; // bottom left: below vmin
        values[nx * ny - 1] = f64::INFINITY; // top right: above vmax
        let mut img = field(&values, nx, ny);
        img.title = "";
        img.extent = (-0.5, 0.5, 0.0, 1.0);
        write_field_png(&path, &img, FieldSize::MapWidth(300)).unwrap();
        let (w, _, rgb) = decode(&path);
        let (left, top, m) = (FIELD_OUTER + FIELD_LEFT, field_title_height(""), 300);
        assert_eq!(pixel(&rgb, w, left + m / 2, top + m / 2), NAN_COLOR);
        assert!(close(pixel(&rgb, w, left + 4, top + m - 5), viridis(0.0), 0));
        assert!(close(pixel(&rgb, w, left + m - 5, top + 4), viridis(1.0), 0));
        assert!(close(pixel(&rgb, w, left + m / 2, top + 20), viridis(0.5), 0));
    }

    #[test]
    fn equal_aspect_ratio_of_the_extent() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("tall.png");
        let values = vec![0.3; 10 * 10];
        let mut img = field(&values, 10, 10);
        img.extent = (0.0, 1.0, 0.0, 2.5); // non-square cells: the extent rules
        write_field_png(&path, &img, FieldSize::MapWidth(120)).unwrap();
        let (_, h, _) = decode(&path);
        assert_eq!(h, field_title_height("ramp") + 300 + FIELD_BOTTOM + FIELD_OUTER);
    }

    #[test]
    fn field_input_errors() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bad.png");
        let values = vec![0.0; 12];
        let ok = field(&values, 4, 3);
        let cases: Vec<(FieldImage, FieldSize, &str)> = vec![
            (FieldImage { nx: 5, ..ok.clone() }, FieldSize::PixelsPerNode(2), "12 values"),
            (
                FieldImage { nx: 0, ny: 0, values: &[], ..ok.clone() },
                FieldSize::PixelsPerNode(2),
                "empty field",
            ),
            (FieldImage { vmin: 1.0, vmax: 1.0, ..ok.clone() }, FieldSize::PixelsPerNode(2), "vmin < vmax"),
            (FieldImage { vmin: f64::NAN, ..ok.clone() }, FieldSize::PixelsPerNode(2), "colour range"),
            (FieldImage { vmax: f64::INFINITY, ..ok.clone() }, FieldSize::PixelsPerNode(2), "colour range"),
            (
                FieldImage { extent: (1.0, 0.0, 0.0, 1.0), ..ok.clone() },
                FieldSize::PixelsPerNode(2),
                "extent",
            ),
            (
                FieldImage { extent: (0.0, 1.0, 0.0, f64::NAN), ..ok.clone() },
                FieldSize::PixelsPerNode(2),
                "extent",
            ),
            (ok.clone(), FieldSize::PixelsPerNode(0), "empty"),
            (ok.clone(), FieldSize::MapWidth(100_000), "exceeds"),
            (FieldImage { extent: (0.0, 1e6, 0.0, 1.0), ..ok.clone() }, FieldSize::MapWidth(100), "empty"),
        ];
        for (img, size, want) in cases {
            let err = write_field_png(&path, &img, size).unwrap_err();
            let msg = err.to_string();
            assert!(matches!(err, PlotError::Input { .. }), "{msg}");
            assert!(msg.starts_with(&path.display().to_string()), "{msg}");
            assert!(msg.contains(want), "{msg} lacks {want:?}");
        }
        assert_empty(dir.path());
    }

    #[test]
    fn line_plot_two_series_with_legend() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("np.png");
        let a: Vec<(f64, f64)> = (0..100).map(|k| (k as f64 * 0.1, 2.0 + (k as f64 * 0.2).sin())).collect();
        let b: Vec<(f64, f64)> = (0..20).map(|k| (k as f64 * 0.5, 5.0 - 0.1 * k as f64)).collect();
        let plot = LinePlot {
            title: "Power number".into(),
            x_label: "t N".into(),
            y_label: "Np".into(),
            series: vec![
                Series::new("A", a, SeriesStyle::Line),
                Series::new("B", b, SeriesStyle::LinePoints),
            ],
            ..Default::default()
        };
        write_line_png(&path, &plot, 640, 400).unwrap();
        let (w, h, rgb) = decode(&path);
        assert_eq!((w, h), (640, 400));
        let has = |c: RGBColor| rgb.chunks(3).any(|p| p == [c.0, c.1, c.2]);
        assert!(has(PALETTE[0]) && has(PALETTE[1]));
        assert!(!has(PALETTE[2]));
    }

    #[test]
    fn log_axes_gaps_and_fixed_ranges() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("log.png");
        // Non-positive and NaN points are gaps on log axes; the rest is clipped to the ranges.
        let pts = vec![(0.0, 1.0), (1.0, 10.0), (10.0, f64::NAN), (100.0, 1e3), (1e3, -1.0), (1e4, 1e5)];
        let plot = LinePlot {
            series: vec![Series::new("s", pts, SeriesStyle::LinePoints)],
            log_x: true,
            log_y: true,
            y_range: Some((1.0, 1e4)),
            legend: LegendPosition::LowerRight,
            ..Default::default()
        };
        write_line_png(&path, &plot, 400, 300).unwrap();
        assert_eq!(decode(&path).0, 400);
        for (log_x, log_y) in [(true, false), (false, true)] {
            let p = LinePlot { log_x, log_y, y_range: None, ..plot.clone() };
            write_line_png(&path, &p, 400, 300).unwrap();
        }
        // A single point gets a range around it.
        let one = LinePlot {
            series: vec![Series::new("", vec![(3.0, 0.0)], SeriesStyle::Points)],
            ..Default::default()
        };
        write_line_png(&path, &one, 300, 200).unwrap();
    }

    #[test]
    fn line_input_errors() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bad.png");
        let s = |pts: Vec<(f64, f64)>| Series::new("s", pts, SeriesStyle::Line);
        let ok = LinePlot { series: vec![s(vec![(0.0, 1.0), (1.0, 2.0)])], ..Default::default() };
        let cases: Vec<(LinePlot, (u32, u32), &str)> = vec![
            (LinePlot { series: vec![], ..ok.clone() }, (400, 300), "no series"),
            (
                LinePlot { series: vec![s(vec![]), s(vec![])], ..ok.clone() },
                (400, 300),
                "every series is empty",
            ),
            (LinePlot { series: vec![s(vec![(f64::NAN, 1.0)])], ..ok.clone() }, (400, 300), "drawable"),
            (
                LinePlot { series: vec![s(vec![(-1.0, 1.0)])], log_x: true, ..ok.clone() },
                (400, 300),
                "drawable",
            ),
            (LinePlot { x_range: Some((1.0, 1.0)), ..ok.clone() }, (400, 300), "x range"),
            (LinePlot { y_range: Some((0.0, f64::INFINITY)), ..ok.clone() }, (400, 300), "y range"),
            (LinePlot { y_range: Some((0.0, 10.0)), log_y: true, ..ok.clone() }, (400, 300), "positive"),
            (ok.clone(), (10, 300), "size"),
            (ok.clone(), (400, MAX_SIDE + 1), "size"),
        ];
        for (plot, (w, h), want) in cases {
            let err = write_line_png(&path, &plot, w, h).unwrap_err();
            let msg = err.to_string();
            assert!(matches!(err, PlotError::Input { .. }), "{msg}");
            assert!(msg.starts_with(&path.display().to_string()), "{msg}");
            assert!(msg.contains(want), "{msg} lacks {want:?}");
        }
        assert_empty(dir.path());
    }

    #[test]
    fn missing_directory_is_an_io_error_naming_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("no/such/dir/f.png");
        let plot = LinePlot {
            series: vec![Series::new("s", vec![(0.0, 0.0), (1.0, 1.0)], SeriesStyle::Line)],
            ..Default::default()
        };
        let err = write_line_png(&path, &plot, 300, 200).unwrap_err();
        assert!(matches!(err, PlotError::Io { .. }));
        assert!(err.to_string().contains("no/such/dir/f.png"), "{err}");
    }

    #[test]
    fn tick_text() {
        assert_eq!(fmt_linear_tick(0.30000000000000004, 1.0), "0.3");
        assert_eq!(fmt_linear_tick(5.5e-17, 1.0), "0");
        assert_eq!(fmt_linear_tick(250.0, 1000.0), "250");
        assert_eq!(fmt_linear_tick(0.015, 0.05), "0.015");
        assert_eq!(fmt_linear_tick(2e6, 1e7), "2e6");
        assert_eq!(fmt_log_tick(0.01), "0.01");
        assert_eq!(fmt_log_tick(1e-5), "1e-5");
        assert_eq!(fmt_log_tick(1000.0), "1000");
    }

    #[test]
    fn clipping_segments() {
        let b = ((0.0, 1.0), (0.0, 1.0));
        assert_eq!(clip_segment((-1.0, 0.5), (2.0, 0.5), b.0, b.1), Some(((0.0, 0.5), (1.0, 0.5))));
        assert_eq!(clip_segment((0.2, 0.2), (0.4, 0.6), b.0, b.1), Some(((0.2, 0.2), (0.4, 0.6))));
        assert_eq!(clip_segment((2.0, 2.0), (3.0, 3.0), b.0, b.1), None);
        assert_eq!(clip_segment((-1.0, 2.0), (-1.0, -2.0), b.0, b.1), None);
    }

    // ---- SVG ------------------------------------------------------------------------------

    /// Checks that `doc` is well-formed XML as this module writes it: a prolog, one root
    /// element, balanced tags, quoted attributes, and `&` only in the five predefined
    /// entities. Returns the number of elements.
    fn assert_well_formed(doc: &str) -> usize {
        let entity_ok = |t: &str| {
            t.match_indices('&').all(|(k, _)| {
                ["&amp;", "&lt;", "&gt;", "&quot;", "&apos;"].iter().any(|e| t[k..].starts_with(e))
            })
        };
        let rest = doc.strip_prefix("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n").expect("prolog");
        let (mut stack, mut elements, mut roots) = (Vec::<String>::new(), 0, 0);
        let mut rest = rest;
        while let Some(open) = rest.find('<') {
            let text = &rest[..open];
            assert!(entity_ok(text), "bad text {text:?}");
            assert!(!stack.is_empty() || text.trim().is_empty(), "text outside the root: {text:?}");
            let close = rest[open..].find('>').expect("unclosed tag") + open;
            let tag = &rest[open + 1..close];
            rest = &rest[close + 1..];
            if let Some(name) = tag.strip_prefix('/') {
                assert_eq!(stack.pop().as_deref(), Some(name), "mismatched </{name}>");
                continue;
            }
            let self_closing = tag.ends_with('/');
            let body = tag.trim_end_matches('/');
            let name_end = body.find(char::is_whitespace).unwrap_or(body.len());
            let name = &body[..name_end];
            assert!(!name.is_empty() && name.chars().all(|c| c.is_ascii_alphanumeric() || c == ':'));
            // Attributes: name="value" separated by spaces.
            let mut attrs = body[name_end..].trim();
            while !attrs.is_empty() {
                let eq = attrs.find("=\"").unwrap_or_else(|| panic!("bad attributes in <{tag}>"));
                let key = &attrs[..eq];
                assert!(key.chars().all(|c| c.is_ascii_alphanumeric() || c == '-' || c == ':'), "{key:?}");
                let end = attrs[eq + 2..].find('"').expect("unquoted value") + eq + 2;
                assert!(entity_ok(&attrs[eq + 2..end]) && !attrs[eq + 2..end].contains('<'));
                attrs = attrs[end + 1..].trim_start();
            }
            elements += 1;
            if stack.is_empty() {
                roots += 1;
            }
            if !self_closing {
                stack.push(name.to_string());
            }
        }
        assert!(rest.trim().is_empty() && stack.is_empty(), "unclosed {stack:?}");
        assert_eq!(roots, 1);
        elements
    }

    /// The value of attribute `name` in the element text `el`.
    fn attr<'a>(el: &'a str, name: &str) -> &'a str {
        let key = format!(" {name}=\"");
        let k = el.find(&key).unwrap_or_else(|| panic!("no {name} in {el}")) + key.len();
        &el[k..k + el[k..].find('"').unwrap()]
    }

    /// The elements `<name …>` of a document, as their opening tags' text.
    fn elements<'a>(doc: &'a str, name: &str) -> Vec<&'a str> {
        let open = format!("<{name} ");
        doc.match_indices(&open).map(|(k, _)| &doc[k..k + doc[k..].find('>').unwrap()]).collect()
    }

    /// Decodes a PNG held in memory: (width, height, RGB bytes).
    fn decode_bytes(bytes: &[u8]) -> (u32, u32, Vec<u8>) {
        let mut reader = png::Decoder::new(std::io::Cursor::new(bytes)).read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut buf).unwrap();
        assert_eq!(info.color_type, png::ColorType::Rgb);
        buf.truncate(info.buffer_size());
        (info.width, info.height, buf)
    }

    /// The embedded image of an `<image>` element, decoded.
    fn embedded(el: &str) -> (u32, u32, Vec<u8>) {
        use base64::Engine as _;
        let data = attr(el, "xlink:href").strip_prefix("data:image/png;base64,").expect("a PNG data URI");
        decode_bytes(&base64::engine::general_purpose::STANDARD.decode(data).unwrap())
    }

    #[test]
    fn line_svg_is_well_formed_and_laid_out_as_the_png() {
        let dir = tempfile::tempdir().unwrap();
        let (svg_path, png_path) = (dir.path().join("np.svg"), dir.path().join("np.png"));
        let a: Vec<(f64, f64)> = (0..100).map(|k| (k as f64 * 0.1, 2.0 + (k as f64 * 0.2).sin())).collect();
        let b: Vec<(f64, f64)> = (0..20).map(|k| (k as f64 * 0.5, 5.0 - 0.1 * k as f64)).collect();
        let plot = LinePlot {
            title: "Power <number> & \"ratio\"".into(),
            x_label: "t N".into(),
            y_label: "Np = P / (ρ N³ D⁵)".into(),
            series: vec![
                Series::new("A < B", a, SeriesStyle::Line),
                Series::new("B", b, SeriesStyle::LinePoints),
            ],
            ..Default::default()
        };
        write_line_svg(&svg_path, &plot, 640, 400).unwrap();
        write_line_png(&png_path, &plot, 640, 400).unwrap();
        let doc = std::fs::read_to_string(&svg_path).unwrap();
        let n = assert_well_formed(&doc);
        assert!(n < 600, "{n} elements");
        let root = elements(&doc, "svg")[0];
        assert_eq!((attr(root, "width"), attr(root, "height")), ("640", "400"));
        assert_eq!(attr(root, "viewBox"), "0 0 640 400");
        // Text as <text>, escaped, in the bundled font's family.
        assert!(attr(root, "font-family").starts_with("'DejaVu Sans'"));
        assert!(doc.contains(">Power &lt;number&gt; &amp; &quot;ratio&quot;</text>"));
        assert!(doc.contains(">A &lt; B</text>") && doc.contains(">Np = P / (ρ N³ D⁵)</text>"));
        assert!(doc.contains("transform=\"rotate(-90 "), "the y label reads upwards");
        // Series in their colours: the line as one polyline, markers as circles.
        let strokes: Vec<&str> = elements(&doc, "polyline").iter().map(|e| attr(e, "stroke")).collect();
        assert!(strokes.contains(&"#1f77b4") && strokes.contains(&"#ff7f0e"), "{strokes:?}");
        assert!(!doc.contains("#2ca02c"));
        let dots = elements(&doc, "circle").iter().filter(|e| attr(e, "fill") == "#ff7f0e").count();
        assert_eq!(dots, 20 + 1, "20 markers and the legend's");
        // One layout: every vertex of the SVG's black lines (axes, ticks) is black in the PNG.
        let (w, _, rgb) = decode(&png_path);
        let black: Vec<&str> =
            elements(&doc, "polyline").into_iter().filter(|e| attr(e, "stroke") == "#000000").collect();
        assert!(black.len() > 10, "{} black lines", black.len());
        for e in black {
            for p in attr(e, "points").split(' ') {
                let (x, y) = p.split_once(',').unwrap();
                let px = x.parse::<f64>().unwrap().floor() as u32;
                let py = y.parse::<f64>().unwrap().floor() as u32;
                assert!(close(pixel(&rgb, w, px, py), [0, 0, 0], 40), "{e}: PNG pixel ({px}, {py})");
            }
        }
    }

    #[test]
    fn field_svg_embeds_the_png_map_and_clips_outlines() {
        let dir = tempfile::tempdir().unwrap();
        let (svg_path, png_path) = (dir.path().join("f.svg"), dir.path().join("f.png"));
        let (nx, ny, ppn) = (40usize, 30usize, 3u32);
        let mut values: Vec<f64> =
            (0..nx * ny).map(|k| ((k % nx) as f64 / nx as f64 + (k / nx) as f64 / ny as f64) / 2.0).collect();
        values[5 * nx + 7] = f64::NAN;
        let outlines = vec![
            vec![(10.0, 10.0), (20.0, 10.0), (20.0, 20.0), (10.0, 20.0)],
            vec![(35.0, 5.0), (50.0, 5.0), (50.0, 12.0), (35.0, 12.0)], // beyond x1 = 40
            vec![(-9.0, -9.0), (-5.0, -9.0), (-5.0, -5.0)],             // wholly outside
        ];
        let mut img = field(&values, nx, ny);
        img.title = "a & b";
        write_field_png(&png_path, &img, FieldSize::PixelsPerNode(ppn)).unwrap(); // no outlines
        img.outlines = &outlines;
        write_field_svg(&svg_path, &img, FieldSize::PixelsPerNode(ppn)).unwrap();
        let doc = std::fs::read_to_string(&svg_path).unwrap();
        assert_well_formed(&doc);
        assert!(!doc.contains("width=\"1\" height=\"1\""), "no element per pixel");
        let (w, h, rgb) = decode(&png_path);
        let root = elements(&doc, "svg")[0];
        assert_eq!(
            (attr(root, "width"), attr(root, "height")),
            (w.to_string().as_str(), h.to_string().as_str())
        );

        // The map and the colour bar: two images, placed as in the PNG, with its pixels.
        let images = elements(&doc, "image");
        assert_eq!(images.len(), 2);
        let (mw, mh) = (nx as u32 * ppn, ny as u32 * ppn);
        let (left, top) = (FIELD_OUTER + FIELD_LEFT, field_title_height("a & b"));
        let map = images[0];
        let at = |k: &str| attr(map, k).parse::<u32>().unwrap();
        assert_eq!((at("x"), at("y"), at("width"), at("height")), (left, top, mw, mh));
        let (iw, ih, pixels) = embedded(map);
        assert_eq!((iw, ih), (mw, mh));
        // Inside the PNG's frame (a black pixel wide).
        for py in 1..mh - 1 {
            for px in 1..mw - 1 {
                assert_eq!(pixel(&pixels, mw, px, py), pixel(&rgb, w, left + px, top + py), "({px}, {py})");
            }
        }
        let bar = images[1];
        assert_eq!(attr(bar, "x").parse::<u32>().unwrap(), left + mw + FIELD_GAP);
        let (bw, bh, bar_pixels) = embedded(bar);
        assert_eq!((bw, bh), (BAR_WIDTH, mh));
        assert!(close(pixel(&bar_pixels, bw, 5, 0), viridis(1.0), 2));
        assert!(close(pixel(&bar_pixels, bw, 5, bh - 1), viridis(0.0), 2));

        // Outlines: white polylines inside the map's pixels (the second one cut at x1, its
        // part beyond left out and its ring thereby opened in two pieces; the third left out).
        let white: Vec<&str> =
            elements(&doc, "polyline").into_iter().filter(|e| attr(e, "stroke") == "#ffffff").collect();
        assert_eq!(white.len(), 3, "the square, and the cut rectangle in two pieces: {white:?}");
        let mut max_x = 0.0f64;
        for e in &white {
            for p in attr(e, "points").split(' ') {
                let (x, y) = p.split_once(',').unwrap();
                let (x, y): (f64, f64) = (x.parse().unwrap(), y.parse().unwrap());
                assert!(x >= left as f64 && x <= (left + mw) as f64, "{e}");
                assert!(y >= top as f64 && y <= (top + mh) as f64, "{e}");
                max_x = max_x.max(x);
            }
        }
        assert!(max_x > (left + mw - 2) as f64, "the clipped outline reaches the map's edge");
    }

    #[test]
    fn outlines_are_white_lines_on_the_png_map() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("o.png");
        let (nx, ny, ppn) = (50usize, 50usize, 4u32);
        let values = vec![0.0; nx * ny]; // dark everywhere
        let square = vec![vec![(10.0, 10.0), (30.0, 10.0), (30.0, 30.0), (10.0, 30.0)]];
        let mut img = field(&values, nx, ny);
        img.outlines = &square;
        write_field_png(&path, &img, FieldSize::PixelsPerNode(ppn)).unwrap();
        let (w, _, rgb) = decode(&path);
        let (left, top) = (FIELD_OUTER + FIELD_LEFT, field_title_height("ramp"));
        let mh = ny as u32 * ppn;
        // Data (x, y) to the pixel holding it.
        let px = |x: f64, y: f64| (left + (x * ppn as f64) as u32, top + mh - 1 - (y * ppn as f64) as u32);
        let white =
            |(x, y): (u32, u32)| (-1i32..=1).any(|d| pixel(&rgb, w, x, (y as i32 + d) as u32) == [255; 3]);
        let white_x =
            |(x, y): (u32, u32)| (-1i32..=1).any(|d| pixel(&rgb, w, (x as i32 + d) as u32, y) == [255; 3]);
        for t in [12.0, 20.0, 28.0] {
            assert!(white(px(t, 10.0)) && white(px(t, 30.0)), "horizontal edges at {t}");
            assert!(white_x(px(10.0, t)) && white_x(px(30.0, t)), "vertical edges at {t}");
        }
        // Not filled, and nothing elsewhere.
        for (x, y) in [(20.0, 20.0), (15.0, 25.0), (40.0, 40.0), (5.0, 20.0)] {
            assert!(close(pixel(&rgb, w, px(x, y).0, px(x, y).1), viridis(0.0), 0), "({x}, {y})");
        }
        // Without outlines the map is uniform.
        img.outlines = &[];
        write_field_png(&path, &img, FieldSize::PixelsPerNode(ppn)).unwrap();
        let (_, _, plain) = decode(&path);
        for t in [12.0, 20.0, 28.0] {
            let (x, y) = px(t, 10.0);
            assert_eq!(pixel(&plain, w, x, y), viridis(0.0));
            assert_eq!(pixel(&plain, w, x, y + 1), viridis(0.0));
        }
    }

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

    #[test]
    fn xml_escaping() {
        assert_eq!(svg::escape_xml("a<b>&\"c'\u{1}\td"), "a&lt;b&gt;&amp;&quot;c&apos; d");
    }
}
