//! NumPy's NPY (one array) and NPZ (a ZIP of NPY arrays) formats, float64 only.

use super::Series;
use crate::atomic::{stage, Staged};
use crate::error::{Error, Result};
use std::io::Write;
use std::path::Path;

/// NPY magic string and format version 1.0.
const MAGIC: &[u8; 8] = b"\x93NUMPY\x01\x00";

/// Header of a little-endian float64 C-order array of `shape`: magic, version, header length,
/// then the header dictionary padded with spaces and ended by `\n` so that the data starts at a
/// multiple of 64 bytes.
pub fn npy_header(shape: &[usize]) -> Vec<u8> {
    let dims = match shape {
        [n] => format!("({n},)"),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(usize::to_string)
                .collect::<Vec<_>>()
                .join(", ")
        ),
    };
    let dict = format!("{{'descr': '<f8', 'fortran_order': False, 'shape': {dims}, }}");
    // Magic and version (8), length field (2), dictionary, padding, newline.
    let unpadded = MAGIC.len() + 2 + dict.len() + 1;
    let padding = (64 - unpadded % 64) % 64;
    let header_len = (dict.len() + padding + 1) as u16;
    let mut h = Vec::with_capacity(unpadded + padding);
    h.extend_from_slice(MAGIC);
    h.extend_from_slice(&header_len.to_le_bytes());
    h.extend_from_slice(dict.as_bytes());
    h.resize(h.len() + padding, b' ');
    h.push(b'\n');
    h
}

/// Writes `series` as one 2-D NPY array, rows × columns, in the series' column order (see the
/// [module documentation](super)). Names and metadata are not written; [`write()`](super::write())
/// puts them in the sidecar.
pub fn write_npy(series: &Series, path: impl AsRef<Path>) -> Result<()> {
    stage_npy(series, path.as_ref())?.commit()
}

/// Writes the NPY array of `series` under a temporary name beside `path`.
pub(crate) fn stage_npy(series: &Series, path: &Path) -> Result<Staged> {
    series.check()?;
    let (rows, cols) = (series.rows(), series.columns.len());
    stage(path, |w| {
        w.write_all(&npy_header(&[rows, cols]))?;
        let mut row_bytes = Vec::with_capacity(8 * cols);
        for r in 0..rows {
            row_bytes.clear();
            for col in &series.data {
                row_bytes.extend_from_slice(&col[r].to_le_bytes());
            }
            w.write_all(&row_bytes)?;
        }
        Ok(())
    })
}

/// Writes `series` as an NPZ archive: one 1-D NPY array per column, named `<column>.npy`.
/// Metadata is not written; [`write()`](super::write()) puts it in the sidecar.
pub fn write_npz(series: &Series, path: impl AsRef<Path>) -> Result<()> {
    stage_npz(series, path.as_ref())?.commit()
}

/// Writes the NPZ archive of `series` under a temporary name beside `path`.
pub(crate) fn stage_npz(series: &Series, path: &Path) -> Result<Staged> {
    series.check()?;
    // Column names become file names inside the archive.
    for name in &series.columns {
        if name.contains(['/', '\\', '\0']) || name == "." || name == ".." {
            return Err(Error::InvalidSeries(format!(
                "column `{name}` cannot name an NPZ entry (no `/`, `\\`, `.` or `..`)"
            )));
        }
    }
    stage(path, |w| {
        let mut zip = zip::ZipWriter::new(w);
        // Stored (NumPy's own `savez` stores too), with a fixed time stamp: the same data give
        // the same bytes.
        let options = zip::write::SimpleFileOptions::default()
            .compression_method(zip::CompressionMethod::Stored)
            .last_modified_time(zip::DateTime::default());
        let mut entry = Vec::new();
        for (name, col) in series.columns.iter().zip(&series.data) {
            entry.clear();
            entry.extend_from_slice(&npy_header(&[col.len()]));
            for x in col {
                entry.extend_from_slice(&x.to_le_bytes());
            }
            zip.start_file(format!("{name}.npy"), options)
                .map_err(std::io::Error::other)?;
            zip.write_all(&entry)?;
        }
        zip.finish().map_err(std::io::Error::other)?;
        Ok(())
    })
}
