//! Content hashes (BLAKE3) of the files read back to continue work, checked on read.
//!
//! - **Checkpoints** carry theirs inside, as the HDF5 attribute `checksum`
//!   ([`crate::io::checkpoint`]): written with the data in one atomic rename.
//! - **Other files** (a cached bed's `bed.json`) have a sidecar `NAME.blake3` beside them
//!   ([`write_sidecar`], [`verify_sidecar`]), one line in `b3sum`'s format (`HEX  NAME`), so
//!   `b3sum -c` checks it too.
//! - **Directories** of several files (a start pack) have one list, [`LIST_FILE`], of
//!   `HEX  RELATIVE/PATH` lines ([`write_list`], [`verify_list`]).
//!
//! A mismatch is a [`Corrupt`] error that names the file and the remedy. A file without a
//! checksum (written by a slurry from before checksums) is read as it is, with a warning.

use std::io;
use std::path::{Path, PathBuf};

use super::atomic::atomic_write_bytes;

/// The extension of a sidecar checksum file: `bed.json` → `bed.json.blake3`.
pub const SIDECAR_EXT: &str = "blake3";

/// The checksum list of a directory ([`write_list`]).
pub const LIST_FILE: &str = "checksums.blake3";

/// A file whose contents do not match the checksum stored with it.
#[derive(Clone, Debug, thiserror::Error)]
#[error("{}: corrupt: {detail}; {remedy}", file.display())]
pub struct Corrupt {
    /// The damaged file.
    pub file: PathBuf,
    /// What does not match.
    pub detail: String,
    /// What to do about it.
    pub remedy: String,
}

/// The BLAKE3 hash of `bytes` as 64 hex digits.
pub fn hash_hex(bytes: &[u8]) -> String {
    blake3::hash(bytes).to_hex().to_string()
}

/// The first 12 hex digits of a hash, for messages.
fn short(hex: &str) -> &str {
    &hex[..hex.len().min(12)]
}

/// The detail of a [`Corrupt`]: the stored and the computed hash.
pub fn mismatch(stored: &str, computed: &str) -> String {
    format!(
        "its contents do not match the checksum stored with it (blake3 {}… stored, {}… computed): it \
         was changed or damaged after it was written",
        short(stored),
        short(computed)
    )
}

/// The sidecar of `path`: `NAME.blake3` beside it.
pub fn sidecar_path(path: &Path) -> PathBuf {
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(".");
    name.push(SIDECAR_EXT);
    path.with_file_name(name)
}

/// Writes the sidecar of `path` ([`sidecar_path`]) for its present contents, atomically.
///
/// # Errors
/// `path` cannot be read or the sidecar cannot be written.
pub fn write_sidecar(path: &Path) -> io::Result<()> {
    let bytes = std::fs::read(path)?;
    let name = path.file_name().unwrap_or_default().to_string_lossy();
    atomic_write_bytes(&sidecar_path(path), format!("{}  {name}\n", hash_hex(&bytes)).as_bytes())
}

/// The hash of a `HEX  NAME` line (64 hex digits), if it has that form.
fn line_hash(line: &str) -> Option<&str> {
    let hex = line.split_whitespace().next()?;
    (hex.len() == 64 && hex.bytes().all(|b| b.is_ascii_hexdigit())).then_some(hex)
}

/// Whether a file was checked.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Checked {
    /// Its checksum matches.
    Matches,
    /// It has no checksum to check against.
    NoChecksum,
}

/// Checks `bytes`, the contents of `path`, against `path`'s sidecar. `remedy` goes into the
/// error.
///
/// # Errors
/// [`Corrupt`]: the hashes differ, or the sidecar is unreadable or malformed.
pub fn verify_sidecar(path: &Path, bytes: &[u8], remedy: &str) -> Result<Checked, Corrupt> {
    let sidecar = sidecar_path(path);
    let corrupt = |detail: String| Corrupt { file: path.to_path_buf(), detail, remedy: remedy.to_string() };
    let text = match std::fs::read(&sidecar) {
        Ok(t) => t,
        Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(Checked::NoChecksum),
        Err(e) => return Err(corrupt(format!("its checksum {} cannot be read: {e}", sidecar.display()))),
    };
    let text = String::from_utf8_lossy(&text);
    let Some(stored) = text.lines().next().and_then(line_hash) else {
        return Err(corrupt(format!("its checksum file {} is malformed", sidecar.display())));
    };
    let computed = hash_hex(bytes);
    if stored.eq_ignore_ascii_case(&computed) {
        Ok(Checked::Matches)
    } else {
        Err(corrupt(mismatch(stored, &computed)))
    }
}

/// Writes `dir/`[`LIST_FILE`] with the hashes of the files `names` (paths relative to `dir`),
/// atomically.
///
/// # Errors
/// A file cannot be read, or the list cannot be written.
pub fn write_list(dir: &Path, names: &[&str]) -> io::Result<()> {
    let mut text = String::new();
    for name in names {
        let bytes = std::fs::read(dir.join(name))?;
        text.push_str(&format!("{}  {name}\n", hash_hex(&bytes)));
    }
    atomic_write_bytes(&dir.join(LIST_FILE), text.as_bytes())
}

/// Checks the files of `dir` against `dir/`[`LIST_FILE`]; [`Checked::NoChecksum`] when there
/// is no list. `remedy` goes into the error.
///
/// # Errors
/// [`Corrupt`] naming the first file that is missing or differs, or the list if malformed.
pub fn verify_list(dir: &Path, remedy: &str) -> Result<Checked, Corrupt> {
    let list = dir.join(LIST_FILE);
    let corrupt = |file: PathBuf, detail: String| Corrupt { file, detail, remedy: remedy.to_string() };
    let text = match std::fs::read_to_string(&list) {
        Ok(t) => t,
        Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(Checked::NoChecksum),
        Err(e) => return Err(corrupt(list, format!("cannot be read: {e}"))),
    };
    for line in text.lines().filter(|l| !l.trim().is_empty()) {
        let (Some(stored), Some((_, name))) = (line_hash(line), line.split_once("  ")) else {
            return Err(corrupt(list.clone(), format!("malformed line `{line}`")));
        };
        let file = dir.join(name.trim());
        let bytes = std::fs::read(&file).map_err(|e| {
            corrupt(file.clone(), format!("listed in {} but cannot be read: {e}", list.display()))
        })?;
        let computed = hash_hex(&bytes);
        if !stored.eq_ignore_ascii_case(&computed) {
            return Err(corrupt(file, mismatch(stored, &computed)));
        }
    }
    Ok(Checked::Matches)
}

/// What to do about a start pack whose checksums do not match ([`verify_list`]).
pub const START_PACK_REMEDY: &str = "write the pack again from its run (`slurry start-pack RUN PACK`), or \
                                     restore it from the archive's history (git)";

/// Says on stderr that the cache entry `path` (of a `what`) was made from other inputs than the
/// key it is stored under: edited, so not used, and made again.
pub fn report_other_inputs(path: &Path, what: &str) {
    eprintln!(
        "{what}: the cache entry {} was made from other inputs than its key says (edited?): it is made again",
        path.display()
    );
}

/// Reads the JSON file `path` of a cache (`what` names it in messages) if it is whole: its
/// sidecar matches and it parses as `T`. Otherwise `None`, after a line on stderr that says
/// why and that it is made again ([`load_cached_json`]).
pub fn read_cached_json<T: serde::de::DeserializeOwned>(path: &Path, what: &str) -> Option<T> {
    let (value, note) = load_cached_json(path, what);
    if let Some(note) = note {
        eprintln!("{note}");
    }
    value
}

/// [`read_cached_json`] without printing: the value if the file is whole, and the line to
/// print, if any: why it is not used (corrupt, unreadable), or, for a file without a sidecar
/// (cached before checksums were kept, read as it is), a note saying so. A file that does not
/// exist is `(None, None)`.
pub fn load_cached_json<T: serde::de::DeserializeOwned>(
    path: &Path,
    what: &str,
) -> (Option<T>, Option<String>) {
    let Ok(bytes) = std::fs::read(path) else { return (None, None) };
    let note = match verify_sidecar(path, &bytes, "") {
        Ok(Checked::Matches) => None,
        Ok(Checked::NoChecksum) => Some(format!(
            "{what}: {} has no checksum (cached before checksums were kept): used as it is; delete it \
             to make it again",
            path.display()
        )),
        Err(e) => {
            let note = format!(
                "{what}: the cache entry {} is corrupt ({}): it is made again",
                path.display(),
                e.detail
            );
            return (None, Some(note));
        }
    };
    match serde_json::from_slice(&bytes) {
        Ok(v) => (Some(v), note),
        Err(e) => (
            None,
            Some(format!(
                "{what}: the cache entry {} cannot be read ({e}): it is made again",
                path.display()
            )),
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sidecars_catch_one_flipped_bit() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("bed.json");
        std::fs::write(&p, br#"{"density":1.25}"#).unwrap();
        assert_eq!(verify_sidecar(&p, &std::fs::read(&p).unwrap(), "r").unwrap(), Checked::NoChecksum);
        write_sidecar(&p).unwrap();
        assert_eq!(verify_sidecar(&p, &std::fs::read(&p).unwrap(), "r").unwrap(), Checked::Matches);
        let mut bytes = std::fs::read(&p).unwrap();
        bytes[13] ^= 0x01; // 1.25 -> 1.35: '2' (0x32) -> '3' (0x33), one bit
        let e = verify_sidecar(&p, &bytes, "delete it").unwrap_err().to_string();
        assert!(e.contains("corrupt") && e.contains("bed.json") && e.contains("delete it"), "{e}");
        assert!(read_cached_json::<serde_json::Value>(&p, "bed").is_some());
        std::fs::write(&p, &bytes).unwrap();
        assert!(read_cached_json::<serde_json::Value>(&p, "bed").is_none(), "corrupt: made again");
    }

    #[test]
    fn lists_name_the_damaged_file() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("run")).unwrap();
        std::fs::write(dir.path().join("a.json"), b"{}").unwrap();
        std::fs::write(dir.path().join("run/b.toml"), b"x = 1").unwrap();
        assert_eq!(verify_list(dir.path(), "r").unwrap(), Checked::NoChecksum);
        write_list(dir.path(), &["a.json", "run/b.toml"]).unwrap();
        assert_eq!(verify_list(dir.path(), "r").unwrap(), Checked::Matches);
        std::fs::write(dir.path().join("run/b.toml"), b"x = 2").unwrap();
        let e = verify_list(dir.path(), "write it again").unwrap_err();
        assert_eq!(e.file, dir.path().join("run/b.toml"));
        assert!(e.to_string().contains("write it again"));
    }
}
