//! A small SVG backend for `plotters`, drawing into a `String`.
//!
//! Coordinates are the bitmap's pixels: one SVG user unit per pixel, the pixel `(x, y)` the
//! unit square `[x, x + 1] × [y, y + 1]`, so that strokes are centred on pixel centres
//! (`x + ½`) and a figure looks as its PNG does. Text is a `<text>` element in the family
//! "DejaVu Sans" placed with the bundled font's metrics (the same box as the PNG's text);
//! a [`Raster`] is an embedded PNG `<image>` (base64 `data:` URI) of the rectangle's
//! pixels, the same pixels the bitmap gets. Unlike plotters' own SVG backend, this one needs no image library for embedding, sizes
//! text by the em of the bundled font, and anchors it on the font's baseline.

use std::fmt::Write as _;
use std::io;

use base64::Engine as _;
use plotters::style::text_anchor::{HPos, VPos};
use plotters::style::FontTransform;
use plotters_backend::{
    BackendColor, BackendCoord, BackendStyle, BackendTextStyle, DrawingBackend, DrawingErrorKind,
};

use super::canvas::{font_error, text_metrics};
use super::{encode_png, Raster, Surface};

/// Font families of the `<text>` elements: the bundled font first, then look-alikes.
const FONT_FAMILIES: &str = "'DejaVu Sans', 'Bitstream Vera Sans', Verdana, sans-serif";

type SvgResult = Result<(), DrawingErrorKind<io::Error>>;

/// The SVG backend: appends elements to `out`, closes the document on `present`.
pub(super) struct SvgCanvas<'a> {
    out: &'a mut String,
    size: (u32, u32),
    closed: bool,
}

impl<'a> SvgCanvas<'a> {
    /// Starts a `w × h` document in `out` (cleared first).
    pub(super) fn new(out: &'a mut String, (w, h): (u32, u32)) -> Self {
        out.clear();
        let _ = write!(
            out,
            "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n\
             <svg xmlns=\"http://www.w3.org/2000/svg\" xmlns:xlink=\"http://www.w3.org/1999/xlink\" \
             version=\"1.1\" width=\"{w}\" height=\"{h}\" viewBox=\"0 0 {w} {h}\" \
             font-family=\"{FONT_FAMILIES}\">\n"
        );
        SvgCanvas { out, size: (w, h), closed: false }
    }

    /// Appends one element's text (already complete) and a newline.
    fn push(&mut self, element: std::fmt::Arguments) {
        let _ = self.out.write_fmt(element);
        self.out.push('\n');
    }
}

/// `#rrggbb` of a colour.
fn hex(c: BackendColor) -> String {
    let (r, g, b) = c.rgb;
    format!("#{r:02x}{g:02x}{b:02x}")
}

/// The opacity attribute `name="alpha"` (with a leading space), or nothing when opaque.
fn opacity(name: &str, c: BackendColor) -> String {
    if c.alpha >= 1.0 {
        String::new()
    } else {
        format!(" {name}=\"{}\"", fmt_num(c.alpha.clamp(0.0, 1.0)))
    }
}

/// A number with at most 3 decimals and no trailing zeros.
fn fmt_num(v: f64) -> String {
    let s = format!("{v:.3}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" {
        "0".to_string()
    } else {
        s.to_string()
    }
}

/// A pixel's centre coordinate.
fn centre(v: i32) -> String {
    fmt_num(f64::from(v) + 0.5)
}

/// Points of a polyline or polygon through pixel centres.
fn points(path: impl IntoIterator<Item = BackendCoord>) -> (String, usize) {
    let mut s = String::new();
    let mut n = 0;
    for (x, y) in path {
        if n > 0 {
            s.push(' ');
        }
        let _ = write!(s, "{},{}", centre(x), centre(y));
        n += 1;
    }
    (s, n)
}

/// `text` with the XML special characters escaped and characters XML 1.0 forbids dropped.
pub(super) fn escape_xml(text: &str) -> String {
    let mut s = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => s.push_str("&amp;"),
            '<' => s.push_str("&lt;"),
            '>' => s.push_str("&gt;"),
            '"' => s.push_str("&quot;"),
            '\'' => s.push_str("&apos;"),
            '\t' | '\n' | '\r' => s.push(' '),
            c if (c as u32) < 0x20 || c == '\u{fffe}' || c == '\u{ffff}' => {}
            c => s.push(c),
        }
    }
    s
}

/// The stroke attributes of a style (with a leading space).
fn stroke<S: BackendStyle>(style: &S) -> String {
    let c = style.color();
    format!(
        " stroke=\"{}\"{} stroke-width=\"{}\"",
        hex(c),
        opacity("stroke-opacity", c),
        style.stroke_width()
    )
}

impl DrawingBackend for SvgCanvas<'_> {
    type ErrorType = io::Error;

    fn get_size(&self) -> (u32, u32) {
        self.size
    }

    fn ensure_prepared(&mut self) -> SvgResult {
        Ok(())
    }

    fn present(&mut self) -> SvgResult {
        if !self.closed {
            self.out.push_str("</svg>\n");
            self.closed = true;
        }
        Ok(())
    }

    fn draw_pixel(&mut self, (x, y): BackendCoord, color: BackendColor) -> SvgResult {
        if color.alpha > 0.0 {
            let (fill, op) = (hex(color), opacity("fill-opacity", color));
            self.push(format_args!(
                "<rect x=\"{x}\" y=\"{y}\" width=\"1\" height=\"1\" fill=\"{fill}\"{op}/>"
            ));
        }
        Ok(())
    }

    fn draw_line<S: BackendStyle>(&mut self, from: BackendCoord, to: BackendCoord, style: &S) -> SvgResult {
        if style.color().alpha > 0.0 {
            let (x1, y1, x2, y2) = (centre(from.0), centre(from.1), centre(to.0), centre(to.1));
            let st = stroke(style);
            self.push(format_args!(
                "<line x1=\"{x1}\" y1=\"{y1}\" x2=\"{x2}\" y2=\"{y2}\"{st} stroke-linecap=\"square\"/>"
            ));
        }
        Ok(())
    }

    fn draw_rect<S: BackendStyle>(
        &mut self,
        upper_left: BackendCoord,
        bottom_right: BackendCoord,
        style: &S,
        fill: bool,
    ) -> SvgResult {
        let c = style.color();
        if c.alpha <= 0.0 {
            return Ok(());
        }
        let (x0, x1) = (upper_left.0.min(bottom_right.0), upper_left.0.max(bottom_right.0));
        let (y0, y1) = (upper_left.1.min(bottom_right.1), upper_left.1.max(bottom_right.1));
        if fill {
            // The bitmap fills both corner pixels (and clips to the canvas).
            let (fill, op) = (hex(c), opacity("fill-opacity", c));
            let (x0, y0) = (x0.max(0), y0.max(0));
            let (x1, y1) = (x1.min(self.size.0 as i32 - 1), y1.min(self.size.1 as i32 - 1));
            if x1 < x0 || y1 < y0 {
                return Ok(());
            }
            let (w, h) = (x1 - x0 + 1, y1 - y0 + 1);
            self.push(format_args!(
                "<rect x=\"{x0}\" y=\"{y0}\" width=\"{w}\" height=\"{h}\" fill=\"{fill}\"{op}/>"
            ));
        } else {
            let (x, y, st) = (centre(x0), centre(y0), stroke(style));
            let (w, h) = (x1 - x0, y1 - y0);
            self.push(format_args!(
                "<rect x=\"{x}\" y=\"{y}\" width=\"{w}\" height=\"{h}\" fill=\"none\"{st}/>"
            ));
        }
        Ok(())
    }

    fn draw_path<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
        &mut self,
        path: I,
        style: &S,
    ) -> SvgResult {
        if style.color().alpha > 0.0 {
            let (pts, n) = points(path);
            if n > 0 {
                let st = stroke(style);
                self.push(format_args!(
                    "<polyline points=\"{pts}\" fill=\"none\"{st} stroke-linejoin=\"round\" \
                     stroke-linecap=\"round\"/>"
                ));
            }
        }
        Ok(())
    }

    fn draw_circle<S: BackendStyle>(
        &mut self,
        (cx, cy): BackendCoord,
        radius: u32,
        style: &S,
        fill: bool,
    ) -> SvgResult {
        let c = style.color();
        if c.alpha > 0.0 {
            let (cx, cy) = (centre(cx), centre(cy));
            let paint = if fill {
                format!(" fill=\"{}\"{}", hex(c), opacity("fill-opacity", c))
            } else {
                format!(" fill=\"none\"{}", stroke(style))
            };
            self.push(format_args!("<circle cx=\"{cx}\" cy=\"{cy}\" r=\"{radius}\"{paint}/>"));
        }
        Ok(())
    }

    fn fill_polygon<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
        &mut self,
        vert: I,
        style: &S,
    ) -> SvgResult {
        let c = style.color();
        if c.alpha > 0.0 {
            let (pts, n) = points(vert);
            if n > 0 {
                let (fill, op) = (hex(c), opacity("fill-opacity", c));
                self.push(format_args!("<polygon points=\"{pts}\" fill=\"{fill}\"{op}/>"));
            }
        }
        Ok(())
    }

    fn blit_bitmap(&mut self, pos: BackendCoord, (w, h): (u32, u32), src: &[u8]) -> SvgResult {
        let (cols, rows) = (w as usize, h as usize);
        if cols == 0 || rows == 0 || src.len() < cols * rows * 3 {
            return Ok(());
        }
        let raster = Raster { cols, rows, rgb: src[..cols * rows * 3].to_vec() };
        self.draw_raster(pos, (w, h), &raster)
    }

    fn draw_text<S: BackendTextStyle>(&mut self, text: &str, style: &S, (x, y): BackendCoord) -> SvgResult {
        let color = style.color();
        if color.alpha <= 0.0 || text.is_empty() {
            return Ok(());
        }
        let m = text_metrics(style.size(), text).ok_or_else(font_error)?;
        let anchor = style.anchor();
        // Horizontal: the viewer aligns the text's own advance (robust to a substituted
        // font); vertical: the baseline below the box's top, as the bitmap sets it.
        let text_anchor = match anchor.h_pos {
            HPos::Left => "start",
            HPos::Center => "middle",
            HPos::Right => "end",
        };
        let top = match anchor.v_pos {
            VPos::Top => 0,
            VPos::Center => -m.size.1 / 2,
            VPos::Bottom => -m.size.1,
        };
        let baseline = fmt_num(f64::from(y) + f64::from(top) + m.ascent);
        let rotate = match style.transform() {
            FontTransform::None => String::new(),
            FontTransform::Rotate90 => format!(" transform=\"rotate(90 {x} {y})\""),
            FontTransform::Rotate180 => format!(" transform=\"rotate(180 {x} {y})\""),
            FontTransform::Rotate270 => format!(" transform=\"rotate(-90 {x} {y})\""),
        };
        let (size, fill, op, body) =
            (fmt_num(m.em), hex(color), opacity("fill-opacity", color), escape_xml(text));
        self.push(format_args!(
            "<text x=\"{x}\" y=\"{baseline}\" font-size=\"{size}\" text-anchor=\"{text_anchor}\" \
             fill=\"{fill}\"{op}{rotate}>{body}</text>"
        ));
        Ok(())
    }

    fn estimate_text_size<S: BackendTextStyle>(
        &self,
        text: &str,
        style: &S,
    ) -> Result<(u32, u32), DrawingErrorKind<Self::ErrorType>> {
        let m = text_metrics(style.size(), text).ok_or_else(font_error)?;
        Ok((m.size.0.max(0) as u32, m.size.1.max(0) as u32))
    }
}

impl Surface for SvgCanvas<'_> {
    /// Embeds the raster as a PNG image resampled to the rectangle's pixels exactly as the
    /// bitmap resamples it, so that every viewer shows the PNG figure's map (a viewer that
    /// smooths scaled images, as librsvg does, would blur one pixel per node into
    /// gradients); scaled further, the image is asked to stay unsmoothed.
    fn draw_raster(&mut self, (x, y): BackendCoord, (w, h): (u32, u32), raster: &Raster) -> SvgResult {
        let png = if (raster.cols, raster.rows) == (w as usize, h as usize) {
            encode_png(&raster.rgb, w, h)
        } else {
            encode_png(&raster.resample(w, h), w, h)
        }
        .map_err(|e| DrawingErrorKind::DrawingError(io::Error::other(e)))?;
        let data = base64::engine::general_purpose::STANDARD.encode(png);
        self.push(format_args!(
            "<image x=\"{x}\" y=\"{y}\" width=\"{w}\" height=\"{h}\" preserveAspectRatio=\"none\" \
             image-rendering=\"optimizeSpeed\" style=\"image-rendering:pixelated\" \
             xlink:href=\"data:image/png;base64,{data}\"/>"
        ));
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn xml_escaping() {
        assert_eq!(escape_xml("a<b>&\"c'\u{1}\td"), "a&lt;b&gt;&amp;&quot;c&apos; d");
    }
}
