//! Shape families as files: a TOML file whose one table, `[classes]`, names each object class's
//! scenario file (`box = "box.toml"`, paths relative to the file).

use crate::error::{Error, Result};
use std::path::{Path, PathBuf};

/// The classes a shape-family file names, in the file's order: each class's name and the path
/// of its scenario file (relative paths resolved against the file's folder).
pub fn read_classes(path: &Path) -> Result<Vec<(String, PathBuf)>> {
    let origin = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|e| Error::io("read", path, e))?;
    let table: toml::Table = toml::from_str(&text).map_err(|e| Error::Toml {
        origin: origin.clone(),
        message: e.to_string().trim_end().to_string(),
    })?;
    let field = |f: &str, m: &str| Error::Field {
        origin: origin.clone(),
        field: f.to_string(),
        message: m.to_string(),
    };
    if let Some(key) = table.keys().find(|k| *k != "classes") {
        return Err(field(
            key,
            "is not a key of a shape family, whose one table [classes] names each class's \
             scenario file (box = \"box.toml\")",
        ));
    }
    let Some(toml::Value::Table(classes)) = table.get("classes") else {
        return Err(field(
            "classes",
            "is required: a table naming each class's scenario file (box = \"box.toml\")",
        ));
    };
    let dir = path.parent().unwrap_or(Path::new(""));
    classes
        .iter()
        .map(|(name, file)| match file {
            toml::Value::String(f) if !f.is_empty() => Ok((name.clone(), dir.join(f))),
            _ => Err(field(
                &format!("classes.{name}"),
                "must be the path of the class's scenario file (a string)",
            )),
        })
        .collect()
}
