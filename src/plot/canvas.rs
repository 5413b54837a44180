//! A bitmap backend that sets text itself ([`Canvas`]).

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
            super::line::clip_segment(f(from), f(to), (0.0, f64::from(w) - 1.0), (0.0, f64::from(h) - 1.0))
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

    fn draw_text<S: BackendTextStyle>(&mut self, text: &str, style: &S, pos: BackendCoord) -> CanvasResult {
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
