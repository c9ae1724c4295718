//! Scenario families: the `[unknowns]`, `[templates]` and `[grid]` tables of a scenario file
//! (the [`Document`](super::Document) makes the scenario for any values of its unknowns).
//!
//! A family is a scenario file plus the keys an estimator infers. Each unknown is a scenario key
//! (`d`, `v`, `whisker.youngs_modulus`, `objects.0.position.1`, …) with the range of values a
//! user expects; a run of the family at a parameter vector is the file with those keys set to
//! those values, read by the same schema as any file. An unknown may also be given a short
//! `name` to be reported by (`x` for `objects.0.position.0`); `[templates]` and `[grid]` accept
//! either spelling.

use crate::error::{Error, Result};
use toml::{Table, Value};

/// Evenly spaced grid values per unknown when a family gives no `[grid]`.
pub const DEFAULT_GRID_COUNT: usize = 6;

/// Default training margin on each side of an unknown's range, as a fraction of its width.
pub const DEFAULT_MARGIN_FRACTION: f64 = 1.0 / 12.0;

/// The longest name an unknown may be given, in characters.
const MAX_NAME_LEN: usize = 32;

/// One unknown of a family.
#[derive(Debug, Clone, PartialEq)]
pub struct UnknownSpec {
    /// Its scenario key (dotted, as for `--set`).
    pub key: String,
    /// The name it is reported by: the file's `name`, or the key when the file gives none.
    /// Distinct within the family, and no other unknown's key.
    pub name: String,
    /// The range of values the family covers, `[lo, hi]` with `lo < hi`, SI.
    pub range: [f64; 2],
    /// How far training runs may reach beyond the range, `[below, above]`, SI (≥ 0).
    pub margin: [f64; 2],
}

/// The estimation side of a scenario file.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FamilySpec {
    /// The unknowns, in the file's order.
    pub unknowns: Vec<UnknownSpec>,
    /// Template values per unknown (`[templates]`, by key or name): the runs a method under the
    /// paper's budget sees are their Cartesian product. Default: each range's ends and midpoint.
    pub templates: Vec<Vec<f64>>,
    /// Evaluation grid values per unknown (`[grid]`, by key or name), the Cartesian product of
    /// which `vibrissa experiment` scores. Default: [`DEFAULT_GRID_COUNT`] evenly spaced values
    /// across each range.
    pub grid: Vec<Vec<f64>>,
}

impl FamilySpec {
    /// The unknowns' keys, in order.
    pub fn keys(&self) -> Vec<&str> {
        self.unknowns.iter().map(|u| u.key.as_str()).collect()
    }

    /// The unknowns' names, in order (each its key unless the file named it).
    pub fn names(&self) -> Vec<&str> {
        self.unknowns.iter().map(|u| u.name.as_str()).collect()
    }

    /// Reads the three tables; `origin` names the file in errors.
    pub(super) fn from_tables(
        origin: &str,
        unknowns: Option<Table>,
        templates: Option<Table>,
        grid: Option<Table>,
    ) -> Result<Option<FamilySpec>> {
        let field = |f: String, m: String| Error::Field {
            origin: origin.to_string(),
            field: f,
            message: m,
        };
        let Some(unknowns) = unknowns else {
            if templates.is_some() || grid.is_some() {
                let which = if templates.is_some() {
                    "templates"
                } else {
                    "grid"
                };
                return Err(field(
                    which.into(),
                    "needs an [unknowns] table naming the keys it gives values for".into(),
                ));
            }
            return Ok(None);
        };
        let mut spec = FamilySpec::default();
        for (key, value) in flatten(&unknowns, "", true) {
            let name = format!("unknowns.{key}");
            if spec.unknowns.iter().any(|u| u.key == key) {
                return Err(field(
                    name,
                    "is given twice (once quoted, once as nested tables): give it once".into(),
                ));
            }
            let (range, margin, given_name) = match value {
                Value::Table(t) => {
                    for k in t.keys() {
                        if !["range", "margin", "name"].contains(&k.as_str()) {
                            return Err(field(
                                format!("{name}.{k}"),
                                "is not a key of an unknown, which takes range, margin and name"
                                    .into(),
                            ));
                        }
                    }
                    let range = t
                        .get("range")
                        .ok_or_else(|| field(format!("{name}.range"), "is required".into()))?;
                    let range = pair(range).map_err(|m| field(format!("{name}.range"), m))?;
                    let margin = match t.get("margin") {
                        Some(m) => Some(pair(m).map_err(|e| field(format!("{name}.margin"), e))?),
                        None => None,
                    };
                    let given_name = match t.get("name") {
                        Some(n) => {
                            Some(unknown_name(n).map_err(|m| field(format!("{name}.name"), m))?)
                        }
                        None => None,
                    };
                    (range, margin, given_name)
                }
                other => (pair(other).map_err(|m| field(name.clone(), m))?, None, None),
            };
            if range[0] >= range[1] {
                return Err(field(
                    name,
                    format!(
                        "is [{}, {}]: expected [lo, hi] with lo < hi",
                        range[0], range[1]
                    ),
                ));
            }
            let width = range[1] - range[0];
            let margin = margin.unwrap_or([DEFAULT_MARGIN_FRACTION * width; 2]);
            if margin.iter().any(|m| *m < 0.0) {
                return Err(field(
                    format!("{name}.margin"),
                    "expected [below, above], both >= 0".into(),
                ));
            }
            spec.unknowns.push(UnknownSpec {
                name: given_name.unwrap_or_else(|| key.clone()),
                key,
                range,
                margin,
            });
        }
        if spec.unknowns.is_empty() {
            return Err(field(
                "unknowns".into(),
                "is empty: name at least one key, e.g. d = [0.015, 0.030]".into(),
            ));
        }
        // A name must pick out one unknown, whichever spelling a reader looks it up by.
        for (i, u) in spec.unknowns.iter().enumerate() {
            if u.name == u.key {
                continue;
            }
            // Another unknown's key, anywhere; or the name of one before it (so that a repeat
            // is reported where it repeats).
            let key_clash = spec
                .unknowns
                .iter()
                .enumerate()
                .find(|&(j, o)| j != i && o.key == u.name)
                .map(|(_, o)| format!("is the key of another unknown, `{}`", o.key));
            let clash = key_clash.or_else(|| {
                spec.unknowns[..i]
                    .iter()
                    .find(|o| o.name == u.name)
                    .map(|o| format!("is also the name of `{}`", o.key))
            });
            if let Some(clash) = clash {
                return Err(field(
                    format!("unknowns.{}.name", u.key),
                    format!(
                        "`{}` {clash}: names must be distinct and differ from the other unknowns' keys",
                        u.name
                    ),
                ));
            }
        }
        spec.templates = values(origin, "templates", templates, &spec.unknowns, |u| {
            vec![u.range[0], 0.5 * (u.range[0] + u.range[1]), u.range[1]]
        })?;
        spec.grid = values(origin, "grid", grid, &spec.unknowns, |u| {
            let n = DEFAULT_GRID_COUNT;
            (0..n)
                .map(|k| u.range[0] + (u.range[1] - u.range[0]) * k as f64 / (n - 1) as f64)
                .collect()
        })?;
        Ok(Some(spec))
    }
}

/// The leaves of a table as dotted keys. With `specs`, a table holding `range` is a leaf (an
/// unknown's long form), not a level.
fn flatten<'a>(table: &'a Table, prefix: &str, specs: bool) -> Vec<(String, &'a Value)> {
    let mut out = Vec::new();
    for (k, v) in table {
        let key = if prefix.is_empty() {
            k.clone()
        } else {
            format!("{prefix}.{k}")
        };
        match v {
            Value::Table(t) if !(specs && t.contains_key("range")) => {
                out.extend(flatten(t, &key, specs))
            }
            _ => out.push((key, v)),
        }
    }
    out
}

/// An unknown's `name`: 1 to [`MAX_NAME_LEN`] ASCII letters, digits, `_`, `.` or `-`.
fn unknown_name(v: &Value) -> std::result::Result<String, String> {
    let allowed = format!("expected 1 to {MAX_NAME_LEN} ASCII letters, digits, `_`, `.` or `-`");
    let Value::String(s) = v else {
        return Err(format!("is a {}: {allowed}, as a string", v.type_str()));
    };
    if s.is_empty() || s.chars().count() > MAX_NAME_LEN {
        return Err(format!(
            "is `{s}`, {} characters long: {allowed}",
            s.chars().count()
        ));
    }
    if let Some(c) = s
        .chars()
        .find(|c| !(c.is_ascii_alphanumeric() || matches!(c, '_' | '.' | '-')))
    {
        return Err(format!("is `{s}`, which holds {c:?}: {allowed}"));
    }
    Ok(s.clone())
}

/// A number (integers too).
fn number(v: &Value) -> Option<f64> {
    match v {
        Value::Float(x) => Some(*x),
        Value::Integer(i) => Some(*i as f64),
        _ => None,
    }
}

/// `[a, b]` of finite numbers.
fn pair(v: &Value) -> std::result::Result<[f64; 2], String> {
    let list = list(v)?;
    match list[..] {
        [a, b] => Ok([a, b]),
        _ => Err(format!("has {} values: expected two, [lo, hi]", list.len())),
    }
}

/// An array of finite numbers.
fn list(v: &Value) -> std::result::Result<Vec<f64>, String> {
    let Value::Array(a) = v else {
        return Err(format!(
            "is a {}: expected an array of numbers",
            v.type_str()
        ));
    };
    a.iter()
        .map(|x| match number(x) {
            Some(x) if x.is_finite() => Ok(x),
            _ => Err(format!("holds `{x}`: expected finite numbers")),
        })
        .collect()
}

/// Values per unknown from `table` (which must give every unknown, by its key or its name, once,
/// and nothing else), or the defaults.
fn values(
    origin: &str,
    table_name: &str,
    table: Option<Table>,
    unknowns: &[UnknownSpec],
    default: impl Fn(&UnknownSpec) -> Vec<f64>,
) -> Result<Vec<Vec<f64>>> {
    let field = |f: String, m: String| Error::Field {
        origin: origin.to_string(),
        field: f,
        message: m,
    };
    let Some(table) = table else {
        return Ok(unknowns.iter().map(default).collect());
    };
    let given = flatten(&table, "", false);
    for (key, _) in &given {
        if !unknowns.iter().any(|u| &u.key == key || &u.name == key) {
            return Err(field(
                format!("{table_name}.{key}"),
                format!(
                    "names no unknown; the unknowns are {}",
                    unknowns
                        .iter()
                        .map(|u| if u.name == u.key {
                            u.key.clone()
                        } else {
                            format!("{} (named {})", u.key, u.name)
                        })
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            ));
        }
    }
    unknowns
        .iter()
        .map(|u| {
            let by_key = given.iter().find(|(k, _)| *k == u.key);
            let by_name = given.iter().find(|(k, _)| *k == u.name);
            let (spelling, v) = match (by_key, by_name) {
                (Some((_, v)), None) => (&u.key, *v),
                (None, Some((_, v))) => (&u.name, *v),
                (Some((_, v)), Some(_)) if u.name == u.key => (&u.key, *v),
                (Some(_), Some(_)) => {
                    return Err(field(
                        format!("{table_name}.{}", u.name),
                        format!(
                            "is given twice, by its key `{}` and by its name: give it once",
                            u.key
                        ),
                    ));
                }
                (None, None) => {
                    let how = if u.name == u.key {
                        String::new()
                    } else {
                        format!(" (this one by its key or its name, `{}`)", u.name)
                    };
                    return Err(field(
                        format!("{table_name}.{}", u.key),
                        format!("is missing: give values for every unknown{how}"),
                    ));
                }
            };
            let f = format!("{table_name}.{spelling}");
            let xs = list(v).map_err(|m| field(f.clone(), m))?;
            if xs.is_empty() {
                return Err(field(f, "is empty".into()));
            }
            if let Some(x) = xs.iter().find(|x| !(u.range[0]..=u.range[1]).contains(*x)) {
                return Err(field(
                    f,
                    format!(
                        "holds {x}, outside the unknown's range [{}, {}]",
                        u.range[0], u.range[1]
                    ),
                ));
            }
            Ok(xs)
        })
        .collect()
}
