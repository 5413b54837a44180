//! Before a resume: does the history on disk reach the checkpoint?
//!
//! A resumed run continues its time series and particle history from the checkpoint's step
//! `S`. What was written after `S` (by the interrupted run, past its last checkpoint) is cut
//! and computed again, exactly; that is a repair. What is missing at or before `S` (a
//! truncated `timeseries.csv`, a deleted segment of `particles.frames/`) cannot be computed
//! again from the checkpoint, so the resume would leave a gap: [`check_resume_history`] refuses
//! it, naming the steps missing, before any file is changed.
//!
//! Expected at or before `S`: a time-series row at every multiple of `output_every` (and
//! possibly at other steps, where an earlier session of the run ended), in increasing order
//! without repeats; with particles, one frame at the step of each such row, no more, no fewer.
//! A run started from a state pack at step `P` has its history from the first output step
//! after `P` (its checkpoints record `P`, [`super::checkpoint::Checkpoint::history_from`]).

use std::path::Path;

use super::particles::{history_steps, segment_dir};

/// What the resume will repair: rows and frames past the checkpoint's step.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct HistoryRepair {
    /// Time-series rows after the checkpoint's step (to be cut).
    pub rows_after: usize,
    /// Particle frames after the checkpoint's step (to be cut).
    pub frames_after: usize,
}

/// The steps of the complete rows of the time series at `path` (its first line is the
/// header; a last line without its newline, cut by a crash, is not a row).
///
/// # Errors
/// The file cannot be read, or a complete line does not start with a step.
fn row_steps(path: &Path) -> Result<Vec<u64>, String> {
    let text =
        std::fs::read_to_string(path).map_err(|e| format!("{}: cannot be read: {e}", path.display()))?;
    text.split_inclusive('\n')
        .skip(1)
        .filter(|l| l.ends_with('\n'))
        .enumerate()
        .map(|(k, l)| {
            l.split(',').next().and_then(|s| s.parse::<u64>().ok()).ok_or_else(|| {
                format!(
                    "{}: line {} is not a row of the time series: `{}`",
                    path.display(),
                    k + 2,
                    l.trim_end()
                )
            })
        })
        .collect()
}

/// `steps` strictly increasing, or the first step that is not.
fn first_disorder(steps: &[u64]) -> Option<(u64, u64)> {
    steps.windows(2).find(|w| w[1] <= w[0]).map(|w| (w[0], w[1]))
}

/// The missing ones among the multiples of `every` in `0..=last`, or in `from + 1..=last` when
/// `from > 0` (a run started from a state pack at step `from` has no rows up to it):
/// `(count, expected, first, last)`.
fn missing_outputs(have: &[u64], every: u64, from: u64, last: u64) -> Option<(u64, u64, u64, u64)> {
    let every = every.max(1);
    let first = if from == 0 { 0 } else { (from / every + 1) * every };
    let expected = if last < first { 0 } else { (last - first) / every + 1 };
    let mut missing = (0u64, u64::MAX, 0u64);
    let mut k = 0usize;
    for m in (first..=last).step_by(every as usize) {
        while k < have.len() && have[k] < m {
            k += 1;
        }
        if k >= have.len() || have[k] != m {
            missing = (missing.0 + 1, missing.1.min(m), m);
        }
    }
    (missing.0 > 0).then_some((missing.0, expected, missing.1, missing.2))
}

/// A range of missing steps in words.
fn steps_range(count: u64, expected: u64, first: u64, last: u64) -> String {
    if count == 1 {
        format!("step {first} (1 of the {expected} output steps)")
    } else {
        format!("steps {first} to {last} ({count} of the {expected} output steps)")
    }
}

/// Checks that the time series at `timeseries` and, with particles, the particle history at
/// `particles` (`particles.h5` and its segments) reach the checkpoint's step `step` for output
/// every `output_every` steps (module docs), from step 0, or, for a run started from a state
/// pack at step `from > 0`, from the first output step after it (the time series may hold the
/// packed run's rows before it, which the particle history does not). Changes nothing.
///
/// # Errors
/// A message naming the file and the missing (or repeated) steps, and the remedy.
pub fn check_resume_history(
    timeseries: &Path,
    particles: Option<&Path>,
    step: u64,
    output_every: u64,
    from: u64,
) -> Result<HistoryRepair, String> {
    let remedy = "the history cannot be computed again from the checkpoint: restore the file from a copy, \
                  or start over with --overwrite";
    let all_rows = row_steps(timeseries)?;
    let rows: Vec<u64> = all_rows.iter().copied().filter(|&s| s <= step).collect();
    let mut repair = HistoryRepair { rows_after: all_rows.len() - rows.len(), frames_after: 0 };
    let rows = &rows[..];
    if let Some((a, b)) = first_disorder(rows) {
        return Err(format!(
            "{}: the row of step {b} follows the row of step {a} (a repeated or misplaced row, as from two \
             runs writing into one directory); {remedy}",
            timeseries.display()
        ));
    }
    if let Some((count, expected, first, last)) = missing_outputs(rows, output_every, from, step) {
        return Err(format!(
            "{}: no rows for {} up to the checkpoint's step {step} (the last row kept is {}); {remedy}",
            timeseries.display(),
            steps_range(count, expected, first, last),
            rows.last().map_or("none".to_string(), |s| format!("step {s}"))
        ));
    }
    let Some(path) = particles else { return Ok(repair) };
    let where_ = || format!("{} with {}", path.display(), segment_dir(path).display());
    let all_frames = history_steps(path).map_err(|e| format!("{}: {e}; {remedy}", where_()))?;
    let frames: Vec<u64> = all_frames.iter().copied().filter(|&s| s <= step).collect();
    repair.frames_after = all_frames.len() - frames.len();
    let frames = &frames[..];
    if let Some((a, b)) = first_disorder(frames) {
        return Err(format!(
            "{}: the frame of step {b} follows the frame of step {a} (a repeated or misplaced frame); {remedy}",
            where_()
        ));
    }
    // The particle history starts after `from`; a run continued from a state pack carries the
    // packed run's rows before it (its time series goes on as one).
    let rows: Vec<u64> = rows.iter().copied().filter(|&s| from == 0 || s > from).collect();
    let rows = &rows[..];
    if frames != rows {
        let absent: Vec<u64> = rows.iter().copied().filter(|s| frames.binary_search(s).is_err()).collect();
        let extra: Vec<u64> = frames.iter().copied().filter(|s| rows.binary_search(s).is_err()).collect();
        let detail = match (absent.first(), absent.last(), extra.first()) {
            (Some(&first), Some(&last), _) => format!(
                "no frames for {} that the time series has, up to the checkpoint's step {step} (the last \
                 frame kept is {})",
                steps_range(absent.len() as u64, rows.len() as u64, first, last)
                    .replace("output steps", "rows"),
                frames.last().map_or("none".to_string(), |s| format!("step {s}"))
            ),
            (_, _, Some(&s)) => format!("a frame of step {s}, which the time series has no row for"),
            _ => "frames that do not match the time series".to_string(),
        };
        return Err(format!("{}: {detail}; {remedy}", where_()));
    }
    Ok(repair)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn series(dir: &Path, steps: &[u64], tail: &str) -> std::path::PathBuf {
        let p = dir.join("timeseries.csv");
        let mut t = String::from("step,time,mass\n");
        for s in steps {
            t.push_str(&format!("{s},{s},1\n"));
        }
        t.push_str(tail);
        std::fs::write(&p, t).unwrap();
        p
    }

    #[test]
    fn rows_past_the_checkpoint_are_a_repair_and_gaps_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let p = series(dir.path(), &[0, 10, 20, 30, 40], "50,5");
        assert_eq!(check_resume_history(&p, None, 20, 10, 0).unwrap().rows_after, 2);
        // An earlier session's end between outputs is allowed.
        let p = series(dir.path(), &[0, 10, 15, 20], "");
        assert_eq!(check_resume_history(&p, None, 20, 10, 0).unwrap(), HistoryRepair::default());
        // Truncated: rows 30 and 40 missing before a checkpoint at 40.
        let p = series(dir.path(), &[0, 10, 20], "3");
        let e = check_resume_history(&p, None, 40, 10, 0).unwrap_err();
        assert!(
            e.contains("steps 30 to 40 (2 of the 5 output steps)") && e.contains("last row kept is step 20"),
            "{e}"
        );
        let p = series(dir.path(), &[0, 10, 20, 10, 20], "");
        let e = check_resume_history(&p, None, 20, 10, 0).unwrap_err();
        assert!(e.contains("step 10 follows the row of step 20"), "{e}");
    }

    /// A run started from a state pack at step 20 has rows from 30 on: none are expected
    /// before, and one missing after is still a gap.
    #[test]
    fn a_run_from_a_pack_has_rows_from_after_the_pack() {
        let dir = tempfile::tempdir().unwrap();
        let p = series(dir.path(), &[30, 40, 50], "");
        assert_eq!(check_resume_history(&p, None, 50, 10, 20).unwrap(), HistoryRepair::default());
        assert_eq!(check_resume_history(&p, None, 20, 10, 20).unwrap().rows_after, 3);
        let e = check_resume_history(&p, None, 50, 10, 0).unwrap_err();
        assert!(e.contains("steps 0 to 20 (3 of the 6 output steps)"), "{e}");
        let p = series(dir.path(), &[30, 50], "");
        let e = check_resume_history(&p, None, 50, 10, 20).unwrap_err();
        assert!(e.contains("step 40 (1 of the 3 output steps)"), "{e}");
        // A pack between outputs: the first row expected is the next multiple.
        let p = series(dir.path(), &[30, 40], "");
        assert_eq!(check_resume_history(&p, None, 40, 10, 25).unwrap(), HistoryRepair::default());
    }
}
