//! One writer per output directory: an exclusive advisory lock (`flock`) on `DIR/.slurry.lock`,
//! taken before anything is written and held until the process ends.
//!
//! [`claim_output_dir`] checks the path ([`check_output_path`]: valid UTF-8, since the HDF5
//! files inside it are opened by name as text, and not an existing file), creates the directory,
//! and locks it. The lock belongs to the open file, so the kernel releases it when the process
//! ends, however it ends (a kill included): there is no stale marker to clean up. The file
//! itself stays, holding the PID and the command line of the last holder, which a refused
//! second writer names. Claims are kept for the life of the process: a second claim of a
//! directory this process already holds (a resumed leg of the same run) succeeds at once.
//!
//! [`OutputLock::acquire_waiting`] locks a named file for one piece of work that two
//! processes must not do at once (settling one cached bed), waiting for the holder instead of
//! refusing.
//!
//! On a file system that cannot lock (some network mounts answer `ENOLCK`), a warning says so
//! and the directory is used unlocked.

use std::fs::{File, OpenOptions};
use std::io::{Read, Seek, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// The lock file's name inside an output directory.
pub const LOCK_FILE: &str = ".slurry.lock";

/// An output directory that cannot be used: not valid UTF-8, a file, not writable, or held by
/// another process. Its Display says which, naming the path (and the holder).
#[derive(Clone, Debug, thiserror::Error)]
#[error("{0}")]
pub struct OutputRefused(pub String);

/// An exclusive lock on an output directory (module docs); released when dropped or when the
/// process ends.
#[derive(Debug)]
pub struct OutputLock {
    dir: PathBuf,
    /// The open lock file: closing it releases the lock.
    _file: File,
}

impl OutputLock {
    /// Locks the existing directory `dir` (`flag` names it in messages, e.g. `--out`), or
    /// refuses with the holder's PID and command when another open file holds it.
    ///
    /// # Errors
    /// [`OutputRefused`]: the lock file cannot be created, or another process (or another
    /// lock of this one) holds the directory.
    pub fn acquire(dir: &Path, flag: &str) -> Result<OutputLock, OutputRefused> {
        let path = dir.join(LOCK_FILE);
        let (file, holder) = open_and_lock(&path, flag, dir, None)?;
        if let Some(who) = holder {
            return Err(OutputRefused(format!(
                "{flag} {}: the directory is in use by another slurry process, {who}, which \
                 holds {}; wait until it ends or choose another directory",
                dir.display(),
                path.display()
            )));
        }
        Ok(OutputLock { dir: dir.to_path_buf(), _file: file })
    }

    /// Locks the file `path` (created if needed, in an existing directory) for one piece of
    /// work that two processes must not do at once, e.g. settling one cached bed: when another
    /// process holds it, `waiting` is called with the holder's description and the lock is
    /// awaited (the holder's work is then usually there to be reused). `flag` names the
    /// directory's option in messages.
    ///
    /// # Errors
    /// [`OutputRefused`]: the lock file cannot be created or written.
    pub fn acquire_waiting(
        path: &Path,
        flag: &str,
        waiting: impl FnOnce(&str),
    ) -> Result<OutputLock, OutputRefused> {
        let dir = path.parent().unwrap_or(Path::new("."));
        let (file, _) = open_and_lock(path, flag, dir, Some(Box::new(waiting)))?;
        Ok(OutputLock { dir: dir.to_path_buf(), _file: file })
    }

    /// The directory locked.
    pub fn dir(&self) -> &Path {
        &self.dir
    }
}

/// What a waiting lock calls with the holder's description before it waits.
type Waiting<'a> = Box<dyn FnOnce(&str) + 'a>;

/// Opens the lock file `path` (in `dir`, given as `flag`) and locks it. When another holds it:
/// without `wait`, returns the holder's description and no lock; with `wait`, calls it with the
/// description and blocks until the lock is free. Once locked, writes this process's record
/// (`PID\nCOMMAND\n`). On a file system that cannot lock, warns and goes on unlocked.
fn open_and_lock(
    path: &Path,
    flag: &str,
    dir: &Path,
    wait: Option<Waiting<'_>>,
) -> Result<(File, Option<String>), OutputRefused> {
    let mut file =
        OpenOptions::new().read(true).write(true).create(true).truncate(false).open(path).map_err(|e| {
            OutputRefused(format!("{flag} {}: cannot write into the directory: {e}", dir.display()))
        })?;
    match try_lock(&file, false) {
        Ok(()) => {}
        Err(e) if e.raw_os_error() == Some(libc::EWOULDBLOCK) => {
            let holder = holder_record(&mut file);
            let mut lines = holder.lines();
            let who = match (lines.next().filter(|l| !l.is_empty()), lines.next()) {
                (Some(pid), Some(cmd)) => format!("PID {pid} (`{cmd}`)"),
                (Some(pid), None) => format!("PID {pid}"),
                _ => "a process that has not yet recorded its PID".to_string(),
            };
            let Some(wait) = wait else { return Ok((file, Some(who))) };
            wait(&who);
            try_lock(&file, true).map_err(|e| {
                OutputRefused(format!("{flag} {}: cannot wait for {}: {e}", dir.display(), path.display()))
            })?;
        }
        Err(e) => {
            eprintln!(
                "warning: {flag} {}: cannot lock {} ({e}); a second writer would not be detected",
                dir.display(),
                path.display()
            );
        }
    }
    let command: Vec<String> = std::env::args_os().map(|a| a.to_string_lossy().into_owned()).collect();
    let record = format!("{}\n{}\n", std::process::id(), command.join(" "));
    // Written over the old record, then cut to its length: a reader sees this record's
    // lines first at every moment.
    let written = file
        .rewind()
        .and_then(|()| file.write_all(record.as_bytes()))
        .and_then(|()| file.set_len(record.len() as u64))
        .and_then(|()| file.flush());
    written.map_err(|e| {
        OutputRefused(format!("{flag} {}: cannot write {}: {e}", dir.display(), path.display()))
    })?;
    Ok((file, None))
}

/// The holder's record in the lock file (`PID\nCOMMAND\n`), waiting up to half a second for
/// a holder that has just taken the lock to write it (two processes started together).
fn holder_record(file: &mut File) -> String {
    let mut text = String::new();
    for _ in 0..50 {
        text.clear();
        if file.rewind().is_ok() && file.read_to_string(&mut text).is_ok() && text.contains('\n') {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    text
}

/// `flock(LOCK_EX | LOCK_NB)` on `file`, or with `block` `flock(LOCK_EX)` (waits).
#[cfg(unix)]
fn try_lock(file: &File, block: bool) -> std::io::Result<()> {
    use std::os::fd::AsRawFd;
    let op = if block { libc::LOCK_EX } else { libc::LOCK_EX | libc::LOCK_NB };
    // SAFETY: flock on a descriptor this `File` owns and keeps open; no memory is passed.
    let r = unsafe { libc::flock(file.as_raw_fd(), op) };
    if r == 0 {
        Ok(())
    } else {
        Err(std::io::Error::last_os_error())
    }
}

/// No advisory lock where `flock` does not exist: reported as unsupported.
#[cfg(not(unix))]
fn try_lock(_file: &File, _block: bool) -> std::io::Result<()> {
    Err(std::io::Error::from(std::io::ErrorKind::Unsupported))
}

/// The locks this process holds, kept until it ends (module docs).
static HELD: Mutex<Vec<(PathBuf, OutputLock)>> = Mutex::new(Vec::new());

/// Checks that `path` (given as `flag`) can hold slurry's output before anything is run: it
/// is valid UTF-8 (the HDF5 library opens files by name as text: `checkpoint.h5`, `fields.h5`
/// and `particles.h5` could not be written under any other path, which would be found only
/// at the first such write, possibly after every step of a run) and it is not an existing
/// file. Nothing is created.
///
/// # Errors
/// [`OutputRefused`] naming the path and what is wrong with it.
pub fn check_output_path(path: &Path, flag: &str) -> Result<(), OutputRefused> {
    if path.to_str().is_none() {
        return Err(OutputRefused(format!(
            "{flag} {}: the path is not valid UTF-8, and the HDF5 files written into it \
             (checkpoint.h5, fields.h5, particles.h5) need a UTF-8 path; choose another",
            path.display()
        )));
    }
    if path.exists() && !path.is_dir() {
        return Err(OutputRefused(format!(
            "{flag} {}: exists and is not a directory; choose a directory",
            path.display()
        )));
    }
    Ok(())
}

/// Claims the output directory `dir` (given as `flag`) for this process: [`check_output_path`],
/// the directory created if needed, and an [`OutputLock`] on it held until the process ends.
/// A directory this process already holds is claimed again at once.
///
/// # Errors
/// [`OutputRefused`]: the path is unusable or cannot be created, or another process holds it
/// (the message names its PID and command).
pub fn claim_output_dir(dir: &Path, flag: &str) -> Result<(), OutputRefused> {
    check_output_path(dir, flag)?;
    std::fs::create_dir_all(dir)
        .map_err(|e| OutputRefused(format!("{flag} {}: cannot create the directory: {e}", dir.display())))?;
    let key = dir.canonicalize().unwrap_or_else(|_| dir.to_path_buf());
    let mut held = HELD.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    if held.iter().any(|(k, _)| *k == key) {
        return Ok(());
    }
    let lock = OutputLock::acquire(dir, flag)?;
    held.push((key, lock));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_second_lock_is_refused_until_the_first_is_dropped() {
        let dir = tempfile::tempdir().unwrap();
        let first = OutputLock::acquire(dir.path(), "--out").unwrap();
        let refused = OutputLock::acquire(dir.path(), "--out").unwrap_err().to_string();
        assert!(refused.contains("in use"), "{refused}");
        assert!(refused.contains(&format!("PID {}", std::process::id())), "{refused}");
        drop(first);
        OutputLock::acquire(dir.path(), "--out").expect("released with its file");
    }

    /// A waiting lock is told who holds it and gets it once the holder lets go.
    #[test]
    fn a_waiting_lock_waits_for_the_holder() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bed.lock");
        let first = OutputLock::acquire_waiting(&path, "--cache", |_| panic!("free")).unwrap();
        let (tx, rx) = std::sync::mpsc::channel();
        let waiter = {
            let path = path.clone();
            std::thread::spawn(move || {
                let _second =
                    OutputLock::acquire_waiting(&path, "--cache", |who| tx.send(who.to_string()).unwrap())
                        .unwrap();
            })
        };
        let who = rx.recv_timeout(std::time::Duration::from_secs(10)).expect("told that it waits");
        assert!(who.contains(&format!("PID {}", std::process::id())), "{who}");
        assert!(!waiter.is_finished(), "waits while the first holds the lock");
        drop(first);
        waiter.join().unwrap();
    }

    #[test]
    fn claims_are_kept_and_repeatable_in_one_process() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out");
        claim_output_dir(&out, "--out").unwrap();
        claim_output_dir(&out, "--out").expect("held by this process already");
        assert!(OutputLock::acquire(&out, "--out").is_err(), "the claim holds the lock");
    }

    #[test]
    fn paths_that_cannot_hold_output_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("file");
        std::fs::write(&file, b"x").unwrap();
        assert!(check_output_path(&file, "--out").unwrap_err().to_string().contains("not a directory"));
        #[cfg(unix)]
        {
            use std::os::unix::ffi::OsStrExt;
            let bad = dir.path().join(std::ffi::OsStr::from_bytes(b"out-\xff"));
            let e = claim_output_dir(&bad, "--out").unwrap_err().to_string();
            assert!(e.contains("not valid UTF-8"), "{e}");
            assert!(!bad.exists(), "nothing created");
        }
    }
}
