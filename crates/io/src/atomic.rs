//! Writing a file all at once: into a temporary file beside it, renamed into place on success.

use crate::error::{Error, Result};
use std::fs::{self, File, OpenOptions};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Distinguishes temporary files of concurrent writes within one process.
static COUNTER: AtomicU64 = AtomicU64::new(0);

/// A file written in full under a temporary name beside its target, waiting to be renamed into
/// place. Dropped without [`Staged::commit`], the temporary file is removed, so several files
/// can be staged first and put in place only when all of them were written.
#[derive(Debug)]
pub(crate) struct Staged {
    /// The temporary file.
    tmp: PathBuf,
    /// The target.
    path: PathBuf,
    /// Whether the temporary file has been renamed (or removed after a failed rename).
    done: bool,
}

impl Staged {
    /// Renames the temporary file onto the target; on failure it is removed and the target is
    /// left as it was.
    pub(crate) fn commit(mut self) -> Result<()> {
        self.done = true;
        fs::rename(&self.tmp, &self.path).map_err(|e| {
            let _ = fs::remove_file(&self.tmp);
            Error::io("write", &self.path, e)
        })
    }
}

impl Drop for Staged {
    fn drop(&mut self) {
        if !self.done {
            let _ = fs::remove_file(&self.tmp);
        }
    }
}

/// Writes the content of `path` through `body` into a temporary file beside it, flushed to disk.
/// `path` itself is untouched until the result is committed; on any failure the temporary file
/// is removed.
pub(crate) fn stage(
    path: &Path,
    body: impl FnOnce(&mut BufWriter<File>) -> io::Result<()>,
) -> Result<Staged> {
    let name = path
        .file_name()
        .ok_or_else(|| Error::io("write", path, io::Error::other("not a file name")))?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let mut tmp_name = std::ffi::OsString::from(".");
    tmp_name.push(name);
    tmp_name.push(format!(".{}.{n}.tmp", std::process::id()));
    let tmp = dir.join(tmp_name);

    // Create the temporary file; from here on, dropping `staged` removes it.
    let file = OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&tmp)
        .map_err(|e| Error::io("write", path, e))?;
    let staged = Staged {
        tmp,
        path: path.to_path_buf(),
        done: false,
    };
    let mut w = BufWriter::new(file);
    body(&mut w)
        .and_then(|()| w.flush())
        .and_then(|()| w.get_ref().sync_all())
        .map_err(|e| Error::io("write", path, e))?;
    Ok(staged)
}
