//! Output files that appear whole or not at all: written beside their target under a hidden
//! temporary name, then renamed into place (a rename within one folder is atomic).

use anyhow::{bail, Context, Result};
use std::ffi::OsString;
use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Distinguishes the temporary files of one process.
static COUNTER: AtomicU64 = AtomicU64::new(0);

/// A temporary path in `target`'s folder: `.NAME.PID.K.tmp.EXT`, hidden, unique within this
/// process, and ending in `target`'s extension (writers that pick a format by extension still
/// pick the right one).
pub fn temp_beside(target: &Path) -> Result<PathBuf> {
    let name = target
        .file_name()
        .with_context(|| format!("`{}` is not a file name", target.display()))?;
    let k = COUNTER.fetch_add(1, Ordering::Relaxed);
    let mut tmp = OsString::from(".");
    tmp.push(name);
    tmp.push(format!(".{}.{k}.tmp", std::process::id()));
    if let Some(ext) = target.extension() {
        tmp.push(".");
        tmp.push(ext);
    }
    Ok(folder_of(target).join(tmp))
}

/// The folder that holds `path` (`.` for a bare file name).
pub fn folder_of(path: &Path) -> PathBuf {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// Renames the finished temporary file `tmp` onto `target`; on failure `tmp` is removed.
pub fn commit(tmp: &Path, target: &Path) -> Result<()> {
    fs::rename(tmp, target).map_err(|e| {
        let _ = fs::remove_file(tmp);
        anyhow::anyhow!("cannot write `{}`: {e}", target.display())
    })
}

/// A finished file under its temporary name, waiting to be renamed onto its target.
///
/// Dropped without [`Pending::commit`], the temporary file is removed, so an error anywhere
/// between writing and committing leaves nothing behind.
#[derive(Debug)]
pub struct Pending {
    /// The temporary file (absent until written).
    temp: PathBuf,
    /// The final path.
    target: PathBuf,
    /// Whether the temporary file has been renamed into place.
    committed: bool,
}

impl Pending {
    /// A pending file for `target`, with a fresh temporary path beside it (not yet created).
    pub fn beside(target: &Path) -> Result<Pending> {
        Ok(Pending {
            temp: temp_beside(target)?,
            target: target.to_path_buf(),
            committed: false,
        })
    }

    /// The temporary path to write.
    pub fn temp(&self) -> &Path {
        &self.temp
    }

    /// Renames the temporary file onto the target.
    pub fn commit(mut self) -> Result<()> {
        self.committed = true;
        commit(&self.temp, &self.target)
    }
}

impl Drop for Pending {
    fn drop(&mut self) {
        if !self.committed {
            let _ = fs::remove_file(&self.temp);
        }
    }
}

/// Writes `bytes` to `target` through a temporary file renamed into place.
pub fn write_atomic(target: &Path, bytes: &[u8]) -> Result<()> {
    let tmp = temp_beside(target)?;
    let written = fs::File::create_new(&tmp).and_then(|mut f| {
        f.write_all(bytes)?;
        f.sync_all()
    });
    if let Err(e) = written {
        let _ = fs::remove_file(&tmp);
        bail!("cannot write `{}`: {e}", target.display());
    }
    commit(&tmp, target)
}

/// Refuses an output path whose folder does not exist (before any long computation).
pub fn check_folder(target: &Path, flag: &str) -> Result<()> {
    let folder = folder_of(target);
    if !folder.is_dir() {
        bail!(
            "{flag} `{}`: the folder `{}` does not exist (create it first)",
            target.display(),
            folder.display()
        );
    }
    if target.is_dir() {
        bail!(
            "{flag} `{}` is a folder; give a file name",
            target.display()
        );
    }
    Ok(())
}

/// The lower-case extension of `path`, if it has one.
pub fn extension(path: &Path) -> Option<String> {
    path.extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn temporary_names_are_hidden_unique_and_keep_the_extension() {
        let a = temp_beside(Path::new("out/run.png")).unwrap();
        let b = temp_beside(Path::new("out/run.png")).unwrap();
        assert_ne!(a, b);
        assert_eq!(a.parent(), Some(Path::new("out")));
        let name = a.file_name().unwrap().to_str().unwrap();
        assert!(
            name.starts_with(".run.png.") && name.ends_with(".tmp.png"),
            "{name}"
        );
        let bare = temp_beside(Path::new("manifest")).unwrap();
        assert_eq!(bare.parent(), Some(Path::new(".")));
        assert!(bare.to_str().unwrap().ends_with(".tmp"));
    }
}
