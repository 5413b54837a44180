//! Field images: a scalar field on a 2-D grid of nodes as a viridis heat map with ticked axes,
//! a colour bar and outlines ([`write_field_png`], [`write_field_svg`]).

use std::path::Path;

use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::FontTransform;

use super::canvas::Canvas;
#[cfg(doc)]
use super::cylinder_section;
use super::line::{pieces, Axis, Series, SeriesStyle};
use super::svg::SvgCanvas;
use super::ticks::fmt_linear_tick;
use super::{
    font, frame, guarded, paint_raster, write_bytes, write_png, DrawResult, PlotError, Raster, Surface,
    LABEL_FONT, MAX_SIDE, NAN_COLOR, TICK_FONT, TITLE_FONT,
};

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
// Figure
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plot::testing::{
        assert_empty, assert_well_formed, attr, close, decode, elements, embedded, field, pixel,
    };

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
}
