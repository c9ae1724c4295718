//! What the command line's integration tests share.

use std::ffi::OsStr;
use std::path::{Path, PathBuf};

/// A folder of one test's own, under the system's temporary folder (named by the test binary's
/// process and `name`), emptied when made and removed when dropped, so that running the tests
/// leaves nothing behind, even when one fails.
pub struct Scratch(PathBuf);

impl Scratch {
    /// The folder `vibrissa-{kind}-{pid}-{name}`, empty.
    pub fn new(kind: &str, name: &str) -> Scratch {
        let dir =
            std::env::temp_dir().join(format!("vibrissa-{kind}-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("a scratch folder");
        Scratch(dir)
    }

    /// The folder.
    #[allow(dead_code)]
    pub fn path(&self) -> &Path {
        &self.0
    }

    /// The path of `name` in the folder, as an argument.
    #[allow(dead_code)]
    pub fn arg(&self, name: &str) -> String {
        self.0.join(name).display().to_string()
    }

    /// Names of the entries in the folder (hidden ones included), sorted.
    #[allow(dead_code)]
    pub fn entries(&self) -> Vec<String> {
        entries(&self.0)
    }
}

impl std::ops::Deref for Scratch {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<Path> for Scratch {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<OsStr> for Scratch {
    fn as_ref(&self) -> &OsStr {
        self.0.as_os_str()
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Names of the entries of `dir` (hidden ones included), sorted.
#[allow(dead_code)]
pub fn entries(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .expect("a readable folder")
        .map(|e| {
            e.expect("an entry")
                .file_name()
                .to_string_lossy()
                .into_owned()
        })
        .collect();
    names.sort();
    names
}

/// The CSV `text` with every data row's `column` set to `value` (a sensor that recorded
/// nothing); comment lines before the header are kept.
#[allow(dead_code)]
pub fn with_column(text: &str, column: &str, value: &str) -> String {
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let head = lines
        .iter()
        .position(|l| !l.starts_with('#'))
        .expect("a header");
    let at = lines[head]
        .split(',')
        .position(|h| h == column)
        .unwrap_or_else(|| panic!("no column {column}"));
    for line in &mut lines[head + 1..] {
        let mut cells: Vec<&str> = line.split(',').collect();
        cells[at] = value;
        *line = cells.join(",");
    }
    lines.join("\n") + "\n"
}
