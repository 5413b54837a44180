//! `manifest.json` of a reproduction: what was run, by which build, on which host, and in how
//! many sessions (the record an archived run keeps, `reproduce/README.md`, "Running and
//! continuing a campaign").
//!
//! Written atomically at the start of every session (`status = "running"`, the session's
//! `ended` empty) and again at its end (`"finished"`, with the session's wall time, the steps
//! and revolutions done). A run stopped by an error (numerical trouble, a failed write) ends
//! its session with `"stopped: <the error>"`. A `--resume` appends a session, so
//! `restarts = sessions − 1`, and a session without an end was killed. `wall_time_s` sums the
//! sessions that ended.
//!
//! **Revision.** The build's git revision: what `SLURRY_GIT_REVISION` says at run time (an
//! override, for a packager), else the revision `build.rs` embedded when the binary was built
//! (`git describe --always --dirty`, so a build of uncommitted sources says `-dirty`), else
//! `"unknown"` (built outside a git checkout).

use std::path::Path;
use std::time::{SystemTime, UNIX_EPOCH};

use anyhow::Context;
use serde::{Deserialize, Serialize};

use super::ContactOverrides;
use slurry::interrupt::Interrupted;
use slurry::io::atomic_write_bytes;

/// The file name, in the reproduction's output directory.
pub const FILE: &str = "manifest.json";

/// One session of a run: a start, or a resume.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Session {
    /// The command line, as given.
    pub command: Vec<String>,
    /// The build's git revision (module docs).
    pub git_revision: String,
    /// The host's CPU model (`/proc/cpuinfo`), and its hardware threads.
    pub host_cpu: String,
    /// Worker threads of the run.
    pub threads: usize,
    /// Start, UTC (RFC 3339).
    pub started: String,
    /// End, UTC; `None` while running or if the session was interrupted.
    pub ended: Option<String>,
    /// Wall-clock seconds of the session, when it ended.
    pub wall_time_s: Option<f64>,
    /// The checkpoint step a resumed session continued from, recorded when the session starts
    /// (manifests written by older versions have it only for sessions that finished).
    pub resumed_from_step: Option<u64>,
    /// The processor that stepped the stirred run: `"cpu"`, or `"gpu"` (`--device gpu`, the
    /// device backend; the report names the adapter). Manifests written before the device
    /// backend have no such field and read as `"cpu"`.
    #[serde(default = "cpu")]
    pub device: String,
}

fn cpu() -> String {
    "cpu".into()
}

/// The manifest (module docs).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    /// Case name.
    pub case: String,
    /// Scale `s`.
    pub scale: f64,
    /// Revolutions after the ramp asked for (with `until_steady`, the first leg's).
    pub revolutions: f64,
    /// `--until-steady CAP`: the run went on past `revolutions`, in legs of
    /// [`super::STEADY_CHECK_REVOLUTIONS`], until the steady test passed or `CAP` revolutions
    /// were done (`revolutions_done` says where it stopped, the report whether it is steady).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub until_steady: Option<f64>,
    /// Contact settings that differ from the case's.
    pub contacts: ContactOverrides,
    /// Steps of the whole run (ramp and revolutions).
    pub steps: u64,
    /// `"running"`, `"finished"` or `"stopped: <error>"`.
    pub status: String,
    /// Steps done when the last session ended.
    pub steps_done: Option<u64>,
    /// Revolutions after the ramp done when the last session ended.
    pub revolutions_done: Option<f64>,
    /// Sessions after the first.
    pub restarts: usize,
    /// Sum of the ended sessions' wall-clock seconds.
    pub wall_time_s: f64,
    /// Every session, in order.
    pub sessions: Vec<Session>,
    /// The legs the run was stepped in (`run/legs.json`, recorded when a session ends): one
    /// for a run from its bed; a run continued from a state pack counts the packed run's legs,
    /// then its own, its time series one series over all of them. Manifests written before
    /// legs were recorded have none.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub legs: Vec<slurry::io::Leg>,
}

impl Manifest {
    /// Starts a session: a new manifest, or (resuming) the one in `dir` with a session
    /// appended (a new one if there is none or it cannot be read), its target (revolutions,
    /// steps) and contact settings replaced by `first`'s. Written to `dir` atomically.
    ///
    /// # Errors
    /// Writing the file failed.
    pub fn start(dir: &Path, first: Manifest, resume: bool, session: Session) -> anyhow::Result<Manifest> {
        let mut m = match resume.then(|| Self::read(dir)).flatten() {
            // The run's target and contact settings are this session's (a resume may extend
            // the run, or switch the contact scheme); its history stays.
            Some(old) => Manifest {
                steps_done: old.steps_done,
                revolutions_done: old.revolutions_done,
                wall_time_s: old.wall_time_s,
                sessions: old.sessions,
                legs: old.legs,
                ..first
            },
            None => first,
        };
        m.status = "running".into();
        m.sessions.push(session);
        m.restarts = m.sessions.len() - 1;
        m.write(dir)?;
        Ok(m)
    }

    /// Ends the current session: its end and wall time, the steps and revolutions done,
    /// status `"finished"`. Written to `dir` atomically.
    ///
    /// # Errors
    /// Writing the file failed.
    pub fn finish(
        &mut self,
        dir: &Path,
        wall_time_s: f64,
        steps_done: u64,
        revolutions_done: f64,
    ) -> anyhow::Result<()> {
        self.steps_done = Some(steps_done);
        self.revolutions_done = Some(revolutions_done);
        self.end_session(dir, wall_time_s, "finished".into())
    }

    /// Ends the current session on an error: its end and wall time, status
    /// `"stopped: <error>"`, or for a stop that a signal asked for the stop as it reads
    /// (`"stopped by SIGTERM at step …"`, [`Interrupted`]); the steps done stay as the last
    /// finished session left them (the run's time series says how far this one got). Written
    /// to `dir` atomically.
    ///
    /// # Errors
    /// Writing the file failed.
    pub fn stop(&mut self, dir: &Path, wall_time_s: f64, error: &anyhow::Error) -> anyhow::Result<()> {
        let status = match error.downcast_ref::<Interrupted>() {
            Some(stop) => stop.to_string(),
            None => format!("stopped: {error:#}"),
        };
        self.end_session(dir, wall_time_s, status)
    }

    /// The current session's end and wall time, the status, the total wall time; written.
    fn end_session(&mut self, dir: &Path, wall_time_s: f64, status: String) -> anyhow::Result<()> {
        if let Some(s) = self.sessions.last_mut() {
            s.ended = Some(utc_now());
            s.wall_time_s = Some(wall_time_s);
        }
        self.status = status;
        self.wall_time_s = self.sessions.iter().filter_map(|s| s.wall_time_s).sum();
        self.write(dir)
    }

    /// The manifest in `dir`, if there is a readable one.
    pub fn read(dir: &Path) -> Option<Manifest> {
        serde_json::from_str(&std::fs::read_to_string(dir.join(FILE)).ok()?).ok()
    }

    fn write(&self, dir: &Path) -> anyhow::Result<()> {
        let path = dir.join(FILE);
        let json = serde_json::to_string_pretty(self).context("cannot serialise the manifest")? + "\n";
        atomic_write_bytes(&path, json.as_bytes()).with_context(|| format!("cannot write {}", path.display()))
    }
}

/// This session as it starts: the command line, the revision, the host, `threads`, on the CPU
/// (set [`Session::device`] for a run on the device).
pub fn this_session(threads: usize) -> Session {
    Session {
        command: std::env::args().collect(),
        git_revision: git_revision(),
        host_cpu: host_cpu(),
        threads,
        started: utc_now(),
        ended: None,
        wall_time_s: None,
        resumed_from_step: None,
        device: cpu(),
    }
}

/// The build's git revision (module docs).
pub fn git_revision() -> String {
    if let Some(r) = std::env::var("SLURRY_GIT_REVISION").ok().filter(|r| !r.trim().is_empty()) {
        return r.trim().to_string();
    }
    match slurry::BUILD_REVISION {
        "" => "unknown".into(),
        r => r.to_string(),
    }
}

/// The CPU model of `/proc/cpuinfo` and the hardware threads, e.g. `"AMD EPYC 9R14, 2
/// hardware threads"`.
pub fn host_cpu() -> String {
    let model = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|t| {
            t.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split_once(':'))
                .map(|(_, v)| v.trim().to_string())
        })
        .unwrap_or_else(|| "unknown CPU".into());
    let threads = std::thread::available_parallelism().map_or(0, |n| n.get());
    format!("{model}, {threads} hardware threads")
}

/// Now, UTC, as `YYYY-MM-DDTHH:MM:SSZ`.
pub fn utc_now() -> String {
    let secs = SystemTime::now().duration_since(UNIX_EPOCH).map_or(0, |d| d.as_secs());
    utc(secs)
}

/// `secs` after the Unix epoch as `YYYY-MM-DDTHH:MM:SSZ` (proleptic Gregorian calendar; the
/// days-to-date conversion of Hinnant, "chrono-Compatible Low-Level Date Algorithms").
pub fn utc(secs: u64) -> String {
    let (days, rest) = ((secs / 86_400) as i64, secs % 86_400);
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!("{year:04}-{month:02}-{day:02}T{:02}:{:02}:{:02}Z", rest / 3600, rest % 3600 / 60, rest % 60)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn utc_dates_match_known_instants() {
        assert_eq!(utc(0), "1970-01-01T00:00:00Z");
        assert_eq!(utc(951_782_400), "2000-02-29T00:00:00Z");
        assert_eq!(utc(1_795_000_000), "2026-11-18T11:06:40Z");
        assert_eq!(utc(4_107_542_399), "2100-02-28T23:59:59Z");
    }

    #[test]
    fn sessions_accumulate_over_resumes() {
        let dir = tempfile::tempdir().unwrap();
        let first = Manifest {
            case: "pbt-ld2".into(),
            scale: 0.25,
            revolutions: 100.0,
            until_steady: None,
            contacts: ContactOverrides::default(),
            steps: 101_000,
            status: String::new(),
            steps_done: None,
            revolutions_done: None,
            restarts: 0,
            wall_time_s: 0.0,
            sessions: Vec::new(),
            legs: Vec::new(),
        };
        let m = Manifest::start(dir.path(), first.clone(), false, this_session(2)).unwrap();
        assert_eq!((m.status.as_str(), m.restarts), ("running", 0));
        assert_eq!(Manifest::read(dir.path()).unwrap(), m);
        // Interrupted: no finish. The resume appends a session, with the step it continues
        // from on disk before it runs.
        let resumed = Session { resumed_from_step: Some(5000), ..this_session(2) };
        let mut m = Manifest::start(dir.path(), first.clone(), true, resumed).unwrap();
        assert_eq!((m.restarts, m.sessions.len()), (1, 2));
        assert!(m.sessions[0].ended.is_none());
        assert_eq!(Manifest::read(dir.path()).unwrap().sessions[1].resumed_from_step, Some(5000));
        m.finish(dir.path(), 12.5, 101_000, 100.0).unwrap();
        let read = Manifest::read(dir.path()).unwrap();
        assert_eq!(
            (read.status.as_str(), read.wall_time_s, read.steps_done),
            ("finished", 12.5, Some(101_000))
        );
        assert_eq!(read.sessions[1].resumed_from_step, Some(5000));
        // A session stopped by an error ends, says why, and counts its time.
        let mut m = Manifest::start(dir.path(), first.clone(), true, this_session(2)).unwrap();
        let trouble = anyhow::anyhow!("numerical trouble at step 95850: Mach number 0.301");
        m.stop(dir.path(), 3.0, &trouble.context("the run failed")).unwrap();
        let read = Manifest::read(dir.path()).unwrap();
        assert_eq!(
            read.status,
            "stopped: the run failed: numerical trouble at step 95850: Mach number 0.301"
        );
        assert!(read.sessions[2].ended.is_some());
        assert_eq!((read.wall_time_s, read.steps_done, read.restarts), (15.5, Some(101_000), 2));
        // A resume that extends the run under another contact scheme: the target and the
        // settings are the new ones, the history stays.
        let longer = Manifest {
            revolutions: 130.0,
            steps: 131_000,
            contacts: ContactOverrides {
                substeps: Some(2),
                lubrication_limiter: true,
                lubrication_substeps: None,
                implicit_damping: false,
            },
            ..first.clone()
        };
        let m = Manifest::start(dir.path(), longer, true, this_session(2)).unwrap();
        assert_eq!((m.revolutions, m.steps, m.contacts.substeps), (130.0, 131_000, Some(2)));
        assert_eq!((m.sessions.len(), m.wall_time_s, m.steps_done), (4, 15.5, Some(101_000)));
        // A session stopped by a signal says so as the stop reads, without "stopped: ".
        let mut m = m;
        let stop = slurry::interrupt::Interrupted {
            signal: slurry::interrupt::Signal::Terminate,
            step: 96_400,
            saved: "the state is in run/checkpoint.h5".into(),
        };
        m.stop(dir.path(), 2.0, &anyhow::Error::new(stop).context("reproduce pbt-ld2 failed")).unwrap();
        let read = Manifest::read(dir.path()).unwrap();
        assert_eq!(read.status, "stopped by SIGTERM at step 96400: the state is in run/checkpoint.h5");
        assert_eq!((read.sessions.len(), read.wall_time_s), (4, 17.5));
        // A fresh start replaces the record.
        let m = Manifest::start(dir.path(), first, false, this_session(1)).unwrap();
        assert_eq!((m.restarts, m.sessions.len()), (0, 1));
    }
}
