//! Key bookkeeping for case-file errors: the allowed keys of each section (taken from the serde
//! derive itself, so they cannot drift from the structs) and the dotted key at a position in
//! the file text.

use serde::de::{self, Deserialize, Deserializer, Visitor};

/// The field names a derived `Deserialize` struct accepts.
///
/// Runs `T::deserialize` against a deserializer that records the `fields` list serde passes to
/// `deserialize_struct` and then fails; nothing is parsed.
pub(crate) fn struct_fields<'de, T: Deserialize<'de>>() -> &'static [&'static str] {
    let mut fields: &'static [&'static str] = &[];
    let _ = T::deserialize(FieldsOf(&mut fields));
    fields
}

struct FieldsOf<'a>(&'a mut &'static [&'static str]);

impl<'de> Deserializer<'de> for FieldsOf<'_> {
    type Error = de::value::Error;

    fn deserialize_any<V: Visitor<'de>>(self, _visitor: V) -> Result<V::Value, Self::Error> {
        Err(de::Error::custom("not a struct"))
    }

    fn deserialize_struct<V: Visitor<'de>>(
        self,
        _name: &'static str,
        fields: &'static [&'static str],
        _visitor: V,
    ) -> Result<V::Value, Self::Error> {
        *self.0 = fields;
        Err(de::Error::custom("fields recorded"))
    }

    serde::forward_to_deserialize_any! {
        bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string
        bytes byte_buf option unit unit_struct newtype_struct seq tuple
        tuple_struct map enum identifier ignored_any
    }
}

/// 1-based line and column (in characters) of byte `offset` in `text`.
pub(crate) fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let offset = floor_char_boundary(text, offset.min(text.len()));
    let before = &text[..offset];
    let line = before.matches('\n').count() + 1;
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    let column = text[line_start..offset].chars().count() + 1;
    (line, column)
}

fn floor_char_boundary(text: &str, mut i: usize) -> usize {
    while !text.is_char_boundary(i) {
        i -= 1;
    }
    i
}

/// The name inside a table header line `[name]` (comments and spaces stripped).
fn header_name(line: &str) -> Option<String> {
    let t = line.trim();
    let rest = t.strip_prefix('[')?;
    let end = rest.find(']')?;
    Some(rest[..end].trim().trim_matches('[').trim().to_string())
}

/// The section a line belongs to: the name of the last table header at or above it, with
/// the entry's index for arrays of tables (`[[particles]]` → `particles[2]` for the third).
fn section_at(text: &str, line_end: usize) -> Option<String> {
    let mut counts: Vec<(String, usize)> = Vec::new();
    let mut current = None;
    for line in text[..line_end].lines() {
        let Some(name) = header_name(line) else { continue };
        if line.trim_start().starts_with("[[") {
            let i = match counts.iter_mut().find(|(n, _)| *n == name) {
                Some((_, c)) => {
                    *c += 1;
                    *c - 1
                }
                None => {
                    counts.push((name.clone(), 1));
                    0
                }
            };
            current = Some(format!("{name}[{i}]"));
        } else {
            current = Some(name);
        }
    }
    current
}

/// Best-effort dotted key (`section.key`) of the line that contains byte `offset`: the last
/// table header above it and the key left of the line's first `=`. On a header line it is
/// the header's name; on a line with no `=` (continuation of a multi-line array) only the
/// section. Entries of arrays of tables carry their index (`particles[2].diameter`). The line
/// and column are always reported beside it, so a miss costs little.
pub(crate) fn key_at(text: &str, offset: usize) -> Option<String> {
    let offset = floor_char_boundary(text, offset.min(text.len()));
    let line_start = text[..offset].rfind('\n').map_or(0, |i| i + 1);
    let line_end = text[line_start..].find('\n').map_or(text.len(), |i| line_start + i);
    let line = &text[line_start..line_end];
    let section = section_at(text, line_end);
    if header_name(line).is_some() {
        return section;
    }
    let key = line
        .split_once('=')
        .map(|(k, _)| k.trim().trim_matches(|c| c == '"' || c == '\'').to_string())
        .filter(|k| !k.is_empty() && !k.starts_with('#'));
    match (section, key) {
        (Some(s), Some(k)) => Some(format!("{s}.{k}")),
        (None, Some(k)) => Some(k),
        (Some(s), None) => Some(s),
        (None, None) => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(serde::Deserialize)]
    #[allow(dead_code)]
    struct S {
        a: f64,
        #[serde(default)]
        b_c: Option<u32>,
    }

    #[test]
    fn fields_come_from_the_derive() {
        assert_eq!(struct_fields::<S>(), &["a", "b_c"]);
    }

    #[test]
    fn key_at_finds_section_and_key() {
        let t = "[domain]\nnx = 4\n\n[fluid] # c\n  tau = 0.5\nbody_force = [\n 1,\n]\n";
        let at = |s: &str| t.find(s).unwrap();
        assert_eq!(key_at(t, at("4")).as_deref(), Some("domain.nx"));
        assert_eq!(key_at(t, at("0.5")).as_deref(), Some("fluid.tau"));
        assert_eq!(key_at(t, at("[fluid]")).as_deref(), Some("fluid"));
        assert_eq!(key_at(t, at(" 1,")).as_deref(), Some("fluid"));
        assert_eq!(line_column(t, at("0.5")), (5, 9));
    }

    #[test]
    fn key_at_numbers_arrays_of_tables() {
        let t = "[[p]]\nd = 1\n[[q]]\nd = 2\n[[p]]\nd = 3\n[r]\nd = 4\n";
        let at = |s: &str| t.find(s).unwrap();
        assert_eq!(key_at(t, at("1")).as_deref(), Some("p[0].d"));
        assert_eq!(key_at(t, at("2")).as_deref(), Some("q[0].d"));
        assert_eq!(key_at(t, at("3")).as_deref(), Some("p[1].d"));
        assert_eq!(key_at(t, at("4")).as_deref(), Some("r.d"));
        assert_eq!(key_at(t, at("[[p]]\nd = 3")).as_deref(), Some("p[1]"));
    }
}
