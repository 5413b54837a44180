//! Atomic file replacement: write a temporary file beside the target, sync it, rename it.

use std::fs::{self, File};
use std::io;
use std::path::{Path, PathBuf};

/// The temporary path used for `path`: `.NAME.tmp.PID` in the same directory (so that the
/// final rename stays on one file system and is atomic).
pub fn temp_path(path: &Path) -> io::Result<PathBuf> {
    let name = path.file_name().ok_or_else(|| {
        io::Error::new(io::ErrorKind::InvalidInput, format!("{}: not a file path", path.display()))
    })?;
    let mut tmp = std::ffi::OsString::from(".");
    tmp.push(name);
    tmp.push(format!(".tmp.{}", std::process::id()));
    Ok(path.with_file_name(tmp))
}

/// Writes `path` atomically: `write` creates and fills the temporary file whose path it is
/// given; then the temporary file is synced to disk and renamed over `path`, and the
/// directory is synced. On any error the temporary file is removed and `path` is untouched.
pub fn atomic_write<E, F>(path: &Path, write: F) -> Result<(), E>
where
    F: FnOnce(&Path) -> Result<(), E>,
    E: From<io::Error>,
{
    let tmp = temp_path(path)?;
    let result = write(&tmp).and_then(|()| {
        File::open(&tmp)?.sync_all()?;
        fs::rename(&tmp, path)?;
        Ok(())
    });
    if result.is_err() {
        let _ = fs::remove_file(&tmp);
        return result;
    }
    sync_parent(path);
    Ok(())
}

/// [`atomic_write`] of a byte buffer.
pub fn atomic_write_bytes(path: &Path, bytes: &[u8]) -> io::Result<()> {
    atomic_write(path, |tmp| fs::write(tmp, bytes))
}

/// Removes the temporary files of [`temp_path`]'s form (`.NAME.tmp.PID`) that a killed
/// process left in `dir`: those whose process is gone, and this process's own. A file of a
/// process still running (another run writing into the same directory) is left alone.
/// Returns the paths removed. Best effort: an unreadable directory removes nothing.
pub fn remove_stale_temps(dir: &Path) -> Vec<PathBuf> {
    let mut removed = Vec::new();
    let Ok(entries) = fs::read_dir(dir) else { return removed };
    for e in entries.flatten() {
        let name = e.file_name();
        let Some(name) = name.to_str() else { continue };
        let Some(pid) = stale_temp_pid(name) else { continue };
        if (pid == std::process::id() || !process_alive(pid)) && e.file_type().is_ok_and(|t| t.is_file()) {
            let p = e.path();
            if fs::remove_file(&p).is_ok() {
                removed.push(p);
            }
        }
    }
    removed
}

/// The PID of a temporary name `.NAME.tmp.PID`, if `name` has that form.
fn stale_temp_pid(name: &str) -> Option<u32> {
    let rest = name.strip_prefix('.')?;
    let (stem, pid) = rest.rsplit_once(".tmp.")?;
    if stem.is_empty() || pid.is_empty() || !pid.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    pid.parse().ok()
}

/// Whether a process with this PID exists (`kill(pid, 0)`; EPERM means it exists).
#[cfg(unix)]
fn process_alive(pid: u32) -> bool {
    let Ok(pid) = libc::pid_t::try_from(pid) else { return false };
    // SAFETY: signal 0 only checks that the process exists; nothing is sent.
    let r = unsafe { libc::kill(pid, 0) };
    r == 0 || io::Error::last_os_error().raw_os_error() == Some(libc::EPERM)
}

/// Whether a process with this PID exists (assumed so where this cannot be checked).
#[cfg(not(unix))]
fn process_alive(_pid: u32) -> bool {
    true
}

/// Syncs the directory holding `path` so that the rename itself is durable. Best effort:
/// not every platform or file system can open a directory for syncing.
fn sync_parent(path: &Path) {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if let Ok(d) = File::open(dir) {
        let _ = d.sync_all();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_and_replaces() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.txt");
        atomic_write_bytes(&p, b"one").unwrap();
        atomic_write_bytes(&p, b"two").unwrap();
        assert_eq!(fs::read(&p).unwrap(), b"two");
        assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn temp_names_parse() {
        assert_eq!(stale_temp_pid(".checkpoint.h5.tmp.1234"), Some(1234));
        assert_eq!(stale_temp_pid("checkpoint.h5.tmp.1234"), None);
        assert_eq!(stale_temp_pid(".checkpoint.h5.tmp."), None);
        assert_eq!(stale_temp_pid(".x.tmp.12a"), None);
    }

    #[test]
    fn failed_write_leaves_target_and_no_temp() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.txt");
        atomic_write_bytes(&p, b"good").unwrap();
        let r: io::Result<()> = atomic_write(&p, |tmp| {
            fs::write(tmp, b"half")?;
            Err(io::Error::other("boom"))
        });
        assert!(r.is_err());
        assert_eq!(fs::read(&p).unwrap(), b"good");
        assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 1);
    }
}
