//! `key=value` overrides applied to a parsed TOML document before it is read into the schema.

use crate::error::Error;
use toml::{Table, Value};

/// Applies one override to `doc`.
///
/// The key is dotted (`whisker.length`); a numeric part indexes an array (`objects.0.friction`),
/// and the index one past the end appends a new table. Missing levels on the way are created
/// (arrays where the next part is a number, tables otherwise).
/// The value is read as a TOML value (`0.02`, `"w30"`, `[0, 0.6]`, `true`, `inf`), or taken as a
/// bare string if it is not one (`w30`). Whether the key exists in the schema is decided later,
/// when the document is read.
pub(super) fn apply(doc: &mut Table, text: &str) -> crate::error::Result<()> {
    let fail = |message: String| Error::Override {
        text: text.to_string(),
        message,
    };
    let (key, raw) = text
        .split_once('=')
        .ok_or_else(|| fail("expected key=value, e.g. whisker.length=0.04".to_string()))?;
    set_value(doc, key, parse_value(raw.trim())).map_err(fail)
}

/// Sets the dotted `key` of `doc` to `value`, as [`apply`] does; the error says what is wrong
/// with the key.
pub(super) fn set_value(doc: &mut Table, key: &str, value: Value) -> Result<(), String> {
    let parts: Vec<&str> = key.trim().split('.').map(str::trim).collect();
    if parts.iter().any(|p| p.is_empty()) {
        return Err(format!(
            "`{}` is not a dotted key such as whisker.length or objects.0.friction",
            key.trim()
        ));
    }

    // Walk down from the root, creating tables as needed, and set the last part.
    let mut root = Value::Table(std::mem::take(doc));
    let result = set(&mut root, &parts, value, 0);
    if let Value::Table(t) = root {
        *doc = t;
    }
    result
}

/// `raw` as a TOML value, or as a string if it is not one.
fn parse_value(raw: &str) -> Value {
    match toml::from_str::<Table>(&format!("value = {raw}")) {
        Ok(mut t) if t.len() == 1 => t
            .remove("value")
            .unwrap_or_else(|| Value::String(raw.to_string())),
        _ => Value::String(raw.to_string()),
    }
}

/// Sets `parts[depth..]` below `node` (which `parts[..depth]` reached).
fn set(
    node: &mut Value,
    parts: &[&str],
    value: Value,
    depth: usize,
) -> std::result::Result<(), String> {
    let part = parts[depth];
    let here = || {
        if depth == 0 {
            "the document".to_string()
        } else {
            format!("`{}`", parts[..depth].join("."))
        }
    };
    let last = depth + 1 == parts.len();
    let child: &mut Value = match node {
        Value::Table(t) => {
            if last {
                t.insert(part.to_string(), value);
                return Ok(());
            }
            // A missing level is an array if indexed by a number, else a table.
            t.entry(part.to_string()).or_insert_with(|| {
                if parts[depth + 1].parse::<usize>().is_ok() {
                    Value::Array(Vec::new())
                } else {
                    Value::Table(Table::new())
                }
            })
        }
        Value::Array(a) => {
            let len = a.len();
            let k: usize = part.parse().map_err(|_| {
                format!(
                    "{} is an array: index it with a number from 0 to {len}, not `{part}`",
                    here()
                )
            })?;
            if k > len {
                return Err(format!(
                    "{} has {len} entries: index {k} is neither one of them nor the next ({len})",
                    here()
                ));
            }
            if k == len {
                a.push(Value::Table(Table::new()));
            }
            if last {
                a[k] = value;
                return Ok(());
            }
            &mut a[k]
        }
        other => {
            return Err(format!(
                "{} is a {}, not a table or array, so it has no `{part}`",
                here(),
                other.type_str()
            ))
        }
    };
    set(child, parts, value, depth + 1)
}
