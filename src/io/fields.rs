//! Density and velocity fields in HDF5.
//!
//! Layout: `/density` is `f64[nz][ny][nx]` and `/velocity` is `f64[nz][ny][nx][3]`, C order,
//! so x varies fastest — the solver's node order, and what XDMF's `3DCoRectMesh` with
//! `Dimensions="nz ny nx"` expects. Root attributes: `units = "lattice"`, `time_step`,
//! `nx`, `ny`, `nz`.

use std::path::Path;

use hdf5::types::VarLenUnicode;

use super::atomic::atomic_write;
use crate::lattice::Grid;

/// Failure writing a field file.
#[derive(Debug, thiserror::Error)]
pub enum FieldsError {
    /// File-system error (temporary file, sync, rename). Shown once (no source: the
    /// message would otherwise be printed twice by a cause chain).
    #[error("{}", io_message(.0))]
    Io(std::io::Error),
    /// Error from the HDF5 library, shown as one line ([`hdf5_message`]).
    #[error("{}", hdf5_message(.0))]
    Hdf5(hdf5::Error),
    /// Field length does not match the grid.
    #[error("field {name} has {len} values; the {nx} x {ny} x {nz} grid needs {want}")]
    Length {
        /// Dataset name.
        name: &'static str,
        /// Values given.
        len: usize,
        /// Values needed.
        want: usize,
        /// Grid size along x.
        nx: usize,
        /// Grid size along y.
        ny: usize,
        /// Grid size along z.
        nz: usize,
    },
}

impl From<std::io::Error> for FieldsError {
    fn from(e: std::io::Error) -> Self {
        FieldsError::Io(e)
    }
}

impl From<hdf5::Error> for FieldsError {
    fn from(e: hdf5::Error) -> Self {
        FieldsError::Hdf5(e)
    }
}

/// An I/O error for people: "no space left on device" for a full disk (ENOSPC), else the
/// system's message.
pub fn io_message(e: &std::io::Error) -> String {
    if e.raw_os_error() == Some(libc::ENOSPC) || e.kind() == std::io::ErrorKind::StorageFull {
        "no space left on device".into()
    } else {
        e.to_string()
    }
}

/// An HDF5 error as one line: "no space left on device" for a full disk (HDF5's stack then
/// holds `errno = 28` and `bytes actually written = 18446744073709551615`), "permission
/// denied", or `HDF5: ` with the stack's description on one line, without the file-driver
/// details (`time = …, buf = …, total write size = …`).
pub fn hdf5_message(e: &hdf5::Error) -> String {
    let text = e.to_string();
    if text.contains("No space left on device") || text.contains("errno = 28,") {
        return "no space left on device".into();
    }
    if text.contains("Permission denied") || text.contains("errno = 13,") {
        return "permission denied".into();
    }
    let one: Vec<&str> = text.lines().map(str::trim).filter(|l| !l.is_empty()).collect();
    let one = one.join("; ");
    let short = one.split(": time = ").next().unwrap_or(&one);
    format!("HDF5: {short}")
}

/// Writes `rho` and `u` (interior node order, x fastest) at `time_step` to the HDF5 file
/// `path`, atomically.
pub fn write_fields_h5(
    path: &Path,
    grid: Grid,
    time_step: u64,
    rho: &[f64],
    u: &[[f64; 3]],
) -> Result<(), FieldsError> {
    let n = grid.nodes();
    let length =
        |name, len| FieldsError::Length { name, len, want: n, nx: grid.nx, ny: grid.ny, nz: grid.nz };
    if rho.len() != n {
        return Err(length("density", rho.len()));
    }
    if u.len() != n {
        return Err(length("velocity", u.len()));
    }
    let shape = [grid.nz, grid.ny, grid.nx];
    atomic_write(path, |tmp| -> Result<(), FieldsError> {
        let file = hdf5::File::create(tmp)?;
        let units: VarLenUnicode = "lattice".parse().expect("ASCII has no NUL");
        file.new_attr::<VarLenUnicode>().shape(()).create("units")?.write_scalar(&units)?;
        file.new_attr::<u64>().shape(()).create("time_step")?.write_scalar(&time_step)?;
        for (name, v) in [("nx", grid.nx), ("ny", grid.ny), ("nz", grid.nz)] {
            file.new_attr::<u64>().shape(()).create(name)?.write_scalar(&(v as u64))?;
        }
        let d = file.new_dataset::<f64>().shape(shape).create("density")?;
        d.write_raw(rho)?;
        let v = file.new_dataset::<f64>().shape([grid.nz, grid.ny, grid.nx, 3]).create("velocity")?;
        v.write_raw(u.as_flattened())?;
        file.close()?;
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_shapes_attributes_and_x_fastest_order() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("f.h5");
        let g = Grid::new(3, 2, 4);
        let rho: Vec<f64> = (0..g.nodes()).map(|i| i as f64).collect();
        let u: Vec<[f64; 3]> = (0..g.nodes())
            .map(|i| {
                let [x, y, z] = g.coords(i);
                [x as f64, y as f64, z as f64]
            })
            .collect();
        write_fields_h5(&p, g, 42, &rho, &u).unwrap();
        let f = hdf5::File::open(&p).unwrap();
        let d = f.dataset("density").unwrap();
        assert_eq!(d.shape(), vec![4, 2, 3]);
        let v = f.dataset("velocity").unwrap();
        assert_eq!(v.shape(), vec![4, 2, 3, 3]);
        let vals: Vec<f64> = v.read_raw().unwrap();
        // Element [z=3][y=1][x=2] holds (2, 1, 3).
        let at = ((3 * 2 + 1) * 3 + 2) * 3;
        assert_eq!(&vals[at..at + 3], &[2.0, 1.0, 3.0]);
        assert_eq!(d.read_raw::<f64>().unwrap(), rho);
        let t: u64 = f.attr("time_step").unwrap().read_scalar().unwrap();
        assert_eq!(t, 42);
        let units: VarLenUnicode = f.attr("units").unwrap().read_scalar().unwrap();
        assert_eq!(units.as_str(), "lattice");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn length_mismatch_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let g = Grid::new(2, 2, 2);
        let e = write_fields_h5(&dir.path().join("f.h5"), g, 0, &[1.0; 7], &[[0.0; 3]; 8]);
        assert!(matches!(e, Err(FieldsError::Length { len: 7, .. })));
    }
}
