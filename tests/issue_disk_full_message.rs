//! Issue 15, defect 6 (full disk): writing `fields.h5` or a checkpoint on a full disk printed
//! HDF5's error dump twice (the error's text, then again as its source), ending in
//! `bytes actually written = 18446744073709551615`.
//!
//! Expected: one line naming the file and "no space left on device". HDF5's stack text and an
//! ENOSPC I/O error both map to it, and the cause chain (`{:#}`, as the CLI prints errors)
//! holds it once.

use slurry::io::{FieldsError, ParticlesError};

/// What HDF5 1.10–1.14 reports for a `write` that fails with ENOSPC (abridged).
const HDF5_ENOSPC: &str = "H5Dwrite(): can't write data: H5FD_sec2_write(): file write failed: time = Tue Jan  7 \
10:00:00 2025, filename = 'out/.fields.h5.tmp.42', file descriptor = 3, errno = 28, error message = 'No space left \
on device', buf = 0x7f00, total write size = 1769472, bytes this sub-write = 1769472, bytes actually written = \
18446744073709551615, offset = 0";

fn cli_text(e: impl std::error::Error + Send + Sync + 'static) -> String {
    format!("{:#}", anyhow::Error::new(e).context("cannot write out/fields.h5"))
}

#[test]
fn hdf5_full_disk_is_one_line_naming_the_file() {
    let text = cli_text(FieldsError::from(hdf5::Error::from(HDF5_ENOSPC)));
    assert_eq!(text, "cannot write out/fields.h5: no space left on device");
    let text = cli_text(ParticlesError::from(hdf5::Error::from(HDF5_ENOSPC)));
    assert_eq!(text, "cannot write out/fields.h5: no space left on device");
}

#[test]
fn io_full_disk_is_one_line_naming_the_file() {
    let e = std::io::Error::from_raw_os_error(libc::ENOSPC);
    assert_eq!(cli_text(FieldsError::from(e)), "cannot write out/fields.h5: no space left on device");
}

#[test]
fn other_errors_are_printed_once() {
    let e = std::io::Error::from_raw_os_error(libc::EIO);
    let text = cli_text(FieldsError::from(e));
    assert_eq!(text.matches("Input/output error").count(), 1, "{text}");
    let text = cli_text(FieldsError::from(hdf5::Error::from("unable to truncate a file")));
    assert_eq!(text, "cannot write out/fields.h5: HDF5: unable to truncate a file");
}
