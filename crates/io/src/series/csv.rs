//! The contract's CSV: a header row, then one row per sample. Written without comment lines;
//! read with them (`# key = value` comments carry metadata).

use super::{is_column_name, is_meta_key, Series, COLUMN_NAME_RULE};
use crate::atomic::{stage, Staged};
use crate::error::{Error, Result};
use std::fmt::Write as _;
use std::io::Write;
use std::path::Path;

/// Writes `series` as CSV (see the [module documentation](super)): the header row and the data,
/// nothing else. Its metadata is not written; [`write()`](super::write()) puts it in the sidecar.
pub fn write_csv(series: &Series, path: impl AsRef<Path>) -> Result<()> {
    stage_csv(series, path.as_ref())?.commit()
}

/// Writes the CSV of `series` under a temporary name beside `path`.
pub(crate) fn stage_csv(series: &Series, path: &Path) -> Result<Staged> {
    series.check()?;
    stage(path, |w| {
        w.write_all(header_text(series).as_bytes())?;
        let mut line = String::new();
        for row in 0..series.rows() {
            line.clear();
            push_row(&mut line, series, row);
            w.write_all(line.as_bytes())?;
        }
        Ok(())
    })
}

/// The CSV text of `series` (what [`write_csv`] writes), e.g. for standard output.
pub fn to_csv_string(series: &Series) -> Result<String> {
    series.check()?;
    let mut text = header_text(series);
    for row in 0..series.rows() {
        push_row(&mut text, series, row);
    }
    Ok(text)
}

/// The header row. No comment lines come before it: the first line of the file is the header, as
/// every common reader expects by default.
fn header_text(series: &Series) -> String {
    let mut text = series.columns.join(",");
    text.push('\n');
    text
}

/// Appends one data row, newline included.
fn push_row(line: &mut String, series: &Series, row: usize) {
    for (c, col) in series.data.iter().enumerate() {
        if c > 0 {
            line.push(',');
        }
        push_number(line, col[row]);
    }
    line.push('\n');
}

/// Appends `x` with the fewest digits that read back to the same bits: plain decimals for
/// ordinary magnitudes, exponent notation for very small or large ones, `NaN` if not a number.
/// A whole number keeps a decimal point (`0.0`, `1.0`), so that readers which guess a column's
/// type from its first rows (polars) take every column as floating point.
fn push_number(line: &mut String, x: f64) {
    let a = x.abs();
    if x.is_nan() {
        line.push_str("NaN");
    } else if a == 0.0 || (1e-5..1e16).contains(&a) {
        let start = line.len();
        let _ = write!(line, "{x}");
        if !line[start..].contains('.') {
            line.push_str(".0");
        }
    } else {
        let _ = write!(line, "{x:e}");
    }
}

/// Reads a CSV time series (see the [module documentation](super)). Errors name the file, the
/// line and the column.
pub fn read_csv(path: impl AsRef<Path>) -> Result<Series> {
    let path = path.as_ref();
    let text = std::fs::read_to_string(path).map_err(|e| Error::io("read", path, e))?;
    read_csv_str(&text, &path.display().to_string())
}

/// Parses CSV text; `origin` names it in errors.
pub fn read_csv_str(text: &str, origin: &str) -> Result<Series> {
    parse_csv(text, origin).map(|(series, _)| series)
}

/// Parses CSV text into a series and the 1-based line number of each data row.
pub(crate) fn parse_csv(text: &str, origin: &str) -> Result<(Series, Vec<usize>)> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut series = Series::default();
    let mut row_lines = Vec::new();
    let mut header = false;
    for (k, raw) in text.lines().enumerate() {
        let (line_no, line) = (k + 1, raw.trim());
        // Blank lines are skipped; comments may carry `key = value` metadata.
        if line.is_empty() {
            continue;
        }
        if let Some(comment) = line.strip_prefix('#') {
            if let Some((key, value)) = comment.split_once('=') {
                if is_meta_key(key.trim()) {
                    series.set_meta(key.trim(), value.trim());
                }
            }
            continue;
        }
        // The first other line is the header.
        if !header {
            for (c, cell) in line.split(',').enumerate() {
                let name = unquote(cell.trim());
                if name.is_empty() {
                    return Err(Error::data(
                        origin,
                        line_no,
                        format!("column {} of the header has no name", c + 1),
                    ));
                }
                if !is_column_name(name) {
                    return Err(Error::data(
                        origin,
                        line_no,
                        format!(
                            "column {} of the header, {name:?}: {COLUMN_NAME_RULE}",
                            c + 1
                        ),
                    ));
                }
                if series.columns.iter().any(|n| n == name) {
                    return Err(Error::data(
                        origin,
                        line_no,
                        format!("column `{name}` appears twice in the header"),
                    ));
                }
                series.columns.push(name.to_string());
                series.data.push(Vec::new());
            }
            header = true;
            continue;
        }
        // Data rows: one number (or NaN) per column.
        let cells = line.split(',').count();
        if cells != series.columns.len() {
            return Err(Error::data(
                origin,
                line_no,
                format!(
                    "{cells} values, but the header has {} columns",
                    series.columns.len()
                ),
            ));
        }
        for (c, cell) in line.split(',').enumerate() {
            let cell = cell.trim();
            let x = parse_number(cell).ok_or_else(|| {
                let what = if cell.is_empty() {
                    "the cell is empty (write NaN for a missing value)".to_string()
                } else if cell.parse::<f64>().is_ok() {
                    format!("`{cell}` is not finite (allowed: finite numbers or NaN)")
                } else {
                    format!("`{cell}` is not a number")
                };
                Error::data(
                    origin,
                    line_no,
                    format!("column `{}`: {what}", series.columns[c]),
                )
            })?;
            series.data[c].push(x);
        }
        row_lines.push(line_no);
    }
    if !header {
        return Err(Error::data(
            origin,
            0,
            "no header row (the file is empty or holds only comments)",
        ));
    }
    Ok((series, row_lines))
}

/// A finite number or NaN.
fn parse_number(cell: &str) -> Option<f64> {
    cell.parse::<f64>().ok().filter(|x| !x.is_infinite())
}

/// `name` without surrounding double quotes.
fn unquote(name: &str) -> &str {
    name.strip_prefix('"')
        .and_then(|n| n.strip_suffix('"'))
        .unwrap_or(name)
}
