//! Helpers shared by the figures' unit tests: PNG decoding, pixels, a small well-formedness
//! check of SVG documents, attributes and embedded images.

use std::path::Path;

use super::FieldImage;

/// Decodes a PNG: (width, height, RGB bytes).
pub(super) fn decode(path: &Path) -> (u32, u32, Vec<u8>) {
    let file = std::io::BufReader::new(std::fs::File::open(path).unwrap());
    let mut reader = png::Decoder::new(file).read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgb);
    assert_eq!(info.bit_depth, png::BitDepth::Eight);
    buf.truncate(info.buffer_size());
    (info.width, info.height, buf)
}

pub(super) fn pixel(rgb: &[u8], w: u32, x: u32, y: u32) -> [u8; 3] {
    let k = 3 * (y * w + x) as usize;
    [rgb[k], rgb[k + 1], rgb[k + 2]]
}

pub(super) fn close(a: [u8; 3], b: [u8; 3], tol: i32) -> bool {
    a.iter().zip(b).all(|(&p, q)| (p as i32 - q as i32).abs() <= tol)
}

pub(super) fn field<'a>(values: &'a [f64], nx: usize, ny: usize) -> FieldImage<'a> {
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
pub(super) fn assert_empty(dir: &Path) {
    assert_eq!(std::fs::read_dir(dir).unwrap().count(), 0);
}

/// Checks that `doc` is well-formed XML as this module writes it: a prolog, one root
/// element, balanced tags, quoted attributes, and `&` only in the five predefined
/// entities. Returns the number of elements.
pub(super) fn assert_well_formed(doc: &str) -> usize {
    let entity_ok = |t: &str| {
        t.match_indices('&')
            .all(|(k, _)| ["&amp;", "&lt;", "&gt;", "&quot;", "&apos;"].iter().any(|e| t[k..].starts_with(e)))
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
pub(super) fn attr<'a>(el: &'a str, name: &str) -> &'a str {
    let key = format!(" {name}=\"");
    let k = el.find(&key).unwrap_or_else(|| panic!("no {name} in {el}")) + key.len();
    &el[k..k + el[k..].find('"').unwrap()]
}

/// The elements `<name …>` of a document, as their opening tags' text.
pub(super) fn elements<'a>(doc: &'a str, name: &str) -> Vec<&'a str> {
    let open = format!("<{name} ");
    doc.match_indices(&open).map(|(k, _)| &doc[k..k + doc[k..].find('>').unwrap()]).collect()
}

/// Decodes a PNG held in memory: (width, height, RGB bytes).
pub(super) fn decode_bytes(bytes: &[u8]) -> (u32, u32, Vec<u8>) {
    let mut reader = png::Decoder::new(std::io::Cursor::new(bytes)).read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgb);
    buf.truncate(info.buffer_size());
    (info.width, info.height, buf)
}

/// The embedded image of an `<image>` element, decoded.
pub(super) fn embedded(el: &str) -> (u32, u32, Vec<u8>) {
    use base64::Engine as _;
    let data = attr(el, "xlink:href").strip_prefix("data:image/png;base64,").expect("a PNG data URI");
    decode_bytes(&base64::engine::general_purpose::STANDARD.decode(data).unwrap())
}
