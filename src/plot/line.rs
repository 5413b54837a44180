//! Line plots: one or more x–y [`Series`] with a legend, labels, optional fixed ranges and
//! logarithmic axes ([`write_line_png`], [`write_line_svg`]); the clipping of polylines to
//! the axes' ranges, which the field images' outlines use too.

use std::path::Path;

use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::coord::Shift;
use plotters::prelude::*;

use super::canvas::Canvas;
use super::svg::SvgCanvas;
use super::ticks::{fmt_linear_tick, fmt_log_tick};
use super::{
    font, guarded, write_bytes, write_png, DrawResult, PlotError, LABEL_FONT, MAX_SIDE, TICK_FONT, TITLE_FONT,
};

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
pub(super) struct Axis {
    pub(super) log: bool,
}

impl Axis {
    /// The value in axis space, or `None` if it cannot be drawn on this axis.
    pub(super) fn fwd(self, v: f64) -> Option<f64> {
        let a = if self.log { v.log10() } else { v };
        a.is_finite().then_some(a)
    }
    pub(super) fn inv(self, a: f64) -> f64 {
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
pub(super) fn clip_segment(
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
pub(super) struct Pieces {
    pub(super) lines: Vec<Vec<(f64, f64)>>,
    pub(super) markers: Vec<(f64, f64)>,
}

pub(super) fn pieces(s: &Series, ax: Axis, ay: Axis, xr: (f64, f64), yr: (f64, f64)) -> Pieces {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plot::testing::{assert_empty, assert_well_formed, attr, close, decode, elements, pixel};

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
    fn clipping_segments() {
        let b = ((0.0, 1.0), (0.0, 1.0));
        assert_eq!(clip_segment((-1.0, 0.5), (2.0, 0.5), b.0, b.1), Some(((0.0, 0.5), (1.0, 0.5))));
        assert_eq!(clip_segment((0.2, 0.2), (0.4, 0.6), b.0, b.1), Some(((0.2, 0.2), (0.4, 0.6))));
        assert_eq!(clip_segment((2.0, 2.0), (3.0, 3.0), b.0, b.1), None);
        assert_eq!(clip_segment((-1.0, 2.0), (-1.0, -2.0), b.0, b.1), None);
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
}
