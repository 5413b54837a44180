//! Reading a case file within bounds, before anything is parsed: `slurry check /dev/zero` read
//! until memory ran out, and a case of 10⁶ `[[particles]]` (92 MB) peaked at 4.6 GB while its
//! tables were built, past the memory check that runs on the parsed case.
//!
//! [`read_case_text`] refuses what is not a regular file (a device such as `/dev/zero`, a
//! FIFO, a directory: these are never opened) and a file above the size limit
//! ([`DEFAULT_SIZE_LIMIT`], or the environment variable [`SIZE_LIMIT_ENV`]), and reads at most
//! the limit. [`check_parse_memory`] then estimates from the text how many tables the parser
//! will build ([`table_count`]: table headers and inline tables, the particles' among them) and
//! what that costs ([`parse_estimate`]), and refuses a text whose parse does not fit the memory
//! available ([`super::memory::available_memory`]), before the parse.

use std::io::Read;
use std::path::Path;

use super::errors::CaseErrorKind;
use super::memory::{available_memory, fmt_bytes, parse_size};

/// The largest case file read by default: 64 MiB (the paper's largest case is under 10 kB;
/// an explicit particle list of 10⁵ entries about 9 MB).
pub const DEFAULT_SIZE_LIMIT: u64 = 64 << 20;

/// The environment variable that replaces [`DEFAULT_SIZE_LIMIT`] (bytes, or with a suffix `K`,
/// `M`, `G`: powers of 1024).
pub const SIZE_LIMIT_ENV: &str = "SLURRY_CASE_SIZE_LIMIT";

/// Bytes the parser holds per table it builds (the TOML document's table, then the case's
/// entry; measured at about 4.6 kB per `[[particles]]` entry, rounded up).
pub const PARSE_BYTES_PER_TABLE: u64 = 5 << 10;

/// Bytes the parser holds per byte of text (the text, its document, and the values).
pub const PARSE_BYTES_PER_TEXT_BYTE: u64 = 4;

/// The size limit in force: [`SIZE_LIMIT_ENV`] if set and readable, else the default.
pub fn size_limit() -> (u64, String) {
    match std::env::var(SIZE_LIMIT_ENV).ok().and_then(|v| parse_size(&v).map(|b| (b, v))) {
        Some((bytes, v)) => (bytes, format!("{SIZE_LIMIT_ENV}={v}")),
        None => (DEFAULT_SIZE_LIMIT, format!("the default; {SIZE_LIMIT_ENV} sets another")),
    }
}

/// What a file is, in words, when it is not a regular file.
fn not_regular(meta: &std::fs::Metadata) -> Option<&'static str> {
    let t = meta.file_type();
    if t.is_file() {
        return None;
    }
    if t.is_dir() {
        return Some("a directory");
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_char_device() {
            return Some("a character device");
        }
        if t.is_block_device() {
            return Some("a block device");
        }
        if t.is_fifo() {
            return Some("a FIFO (named pipe)");
        }
        if t.is_socket() {
            return Some("a socket");
        }
    }
    Some("not a regular file")
}

/// The text of the case file `path`, read within bounds (module docs).
///
/// # Errors
/// [`CaseErrorKind::Read`] when it cannot be read or is not UTF-8; [`CaseErrorKind::Refused`]
/// when it is not a regular file or exceeds the size limit.
pub fn read_case_text(path: &Path) -> Result<String, CaseErrorKind> {
    let meta = std::fs::metadata(path).map_err(CaseErrorKind::Read)?;
    if let Some(what) = not_regular(&meta) {
        return Err(CaseErrorKind::Refused(format!(
            "{what}, not a regular file: a case file is read only from a regular file (nothing was read)"
        )));
    }
    let (limit, source) = size_limit();
    let too_big = |size: String| {
        CaseErrorKind::Refused(format!(
            "{size}, above the limit of {} for a case file ({source}); nothing was parsed",
            fmt_bytes(limit)
        ))
    };
    if meta.len() > limit {
        return Err(too_big(fmt_bytes(meta.len())));
    }
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    std::fs::File::open(path)
        .and_then(|f| f.take(limit.saturating_add(1)).read_to_end(&mut bytes))
        .map_err(CaseErrorKind::Read)?;
    if bytes.len() as u64 > limit {
        return Err(too_big(format!("more than {}", fmt_bytes(limit))));
    }
    String::from_utf8(bytes).map_err(|e| {
        CaseErrorKind::Read(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("not UTF-8 text: {e}"),
        ))
    })
}

/// The tables the parser will build for `text`, estimated without parsing it: `(all, particles)`
/// where `all` counts the table headers (`[x]`, `[[x]]`) and inline tables (`{`), and
/// `particles` the `[[particles]]` headers and the inline tables on lines of a particle list.
pub fn table_count(text: &str) -> (u64, u64) {
    let (mut all, mut particles) = (0u64, 0u64);
    let mut in_particles = false;
    for line in text.lines() {
        let t = line.trim_start();
        if t.starts_with('[') {
            all += 1;
            in_particles = t.starts_with("[[particles]]");
            particles += u64::from(in_particles);
            continue;
        }
        let braces = t.split('#').next().unwrap_or("").bytes().filter(|&b| b == b'{').count() as u64;
        all += braces;
        if t.starts_with("particles") {
            in_particles = true;
        }
        if in_particles {
            particles += braces;
        }
    }
    (all, particles)
}

/// The memory the parse of `text` needs, estimated (module docs): bytes.
pub fn parse_estimate(text: &str) -> u64 {
    let (tables, _) = table_count(text);
    (text.len() as u64)
        .saturating_mul(PARSE_BYTES_PER_TEXT_BYTE)
        .saturating_add(tables.saturating_mul(PARSE_BYTES_PER_TABLE))
}

/// Refuses `text` when its parse would not fit the memory available (module docs).
///
/// # Errors
/// [`CaseErrorKind::Invalid`] for the key `[[particles]]` (or the file, without particles),
/// naming the count, the estimate and the limit.
pub fn check_parse_memory(text: &str) -> Result<(), CaseErrorKind> {
    let Some(limit) = available_memory() else { return Ok(()) };
    let need = parse_estimate(text);
    if need <= limit.bytes {
        return Ok(());
    }
    let (tables, particles) = table_count(text);
    Err(CaseErrorKind::Invalid {
        key: "[[particles]]".into(),
        value: format!(
            "about {particles} entries ({tables} tables in all, {} of text)",
            fmt_bytes(text.len() as u64)
        ),
        allowed: format!(
            "reading them needs about {}; this machine has {} available ({}): use fewer particles, or \
             [[random_particles]] to place many; nothing was parsed",
            fmt_bytes(need),
            fmt_bytes(limit.bytes),
            limit.source
        ),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tables_are_counted_from_the_text() {
        let text = "[domain]\nnx = 4\n[[particles]]\nshape = \"sphere\"\n[[particles]]\n\
                    shape = \"sphere\"\n[boundaries]\nz_max = { moving_wall = [0.1, 0, 0] } # {\n";
        assert_eq!(table_count(text), (5, 2));
        let inline = "particles = [\n  { shape = \"sphere\" },\n  { shape = \"sphere\" },\n]\n[run]\n";
        assert_eq!(table_count(inline), (3, 2));
        assert!(parse_estimate(text) >= 5 * PARSE_BYTES_PER_TABLE);
    }

    #[cfg(unix)]
    #[test]
    fn devices_and_directories_are_not_read() {
        let e = read_case_text(Path::new("/dev/zero")).unwrap_err().to_string();
        assert!(e.contains("character device"), "{e}");
        let dir = tempfile::tempdir().unwrap();
        assert!(read_case_text(dir.path()).unwrap_err().to_string().contains("a directory"));
    }
}
