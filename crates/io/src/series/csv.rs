//! The contract's CSV: a header row, then one row per sample. Written without comment lines;
//! read with them (`# key = value` comments carry metadata).

use super::{is_column_name, is_meta_key, Series, COLUMN_NAME_RULE};
use crate::atomic::{stage, Staged};
use crate::error::{Error, Result};
use std::fmt::Write as _;
use std::path::Path;

/// Writes `series` as CSV (see the [module documentation](super)): the header row and the data,
/// nothing else. Its metadata is not written; [`write()`](super::write()) puts it in the sidecar.
pub fn write_csv(series: &Series, path: impl AsRef<Path>) -> Result<()> {
    stage_csv(series, path.as_ref())?.commit()
}

/// Writes the CSV of `series` under a temporary name beside `path`.
pub(crate) fn stage_csv(series: &Series, path: &Path) -> Result<Staged> {
    series.check()?;
    stage(path, |w| write_records(series, w))
}

/// The CSV text of `series` (what [`write_csv`] writes), e.g. for standard output.
pub fn to_csv_string(series: &Series) -> Result<String> {
    series.check()?;
    let mut bytes = Vec::new();
    write_records(series, &mut bytes).map_err(|e| Error::InvalidSeries(e.to_string()))?;
    String::from_utf8(bytes).map_err(|e| Error::InvalidSeries(e.to_string()))
}

/// The header row, then one record per row, `\n`-terminated. No comment lines come before the
/// header: the first line of the file is the header, as every common reader expects by default.
/// (Checked column names and numbers never need quoting.)
fn write_records(series: &Series, out: impl std::io::Write) -> std::io::Result<()> {
    let mut w = csv::WriterBuilder::new()
        .terminator(csv::Terminator::Any(b'\n'))
        .from_writer(out);
    w.write_record(&series.columns)?;
    let mut cells: Vec<String> = vec![String::new(); series.columns.len()];
    for row in 0..series.rows() {
        for (cell, col) in cells.iter_mut().zip(&series.data) {
            cell.clear();
            push_number(cell, col[row]);
        }
        w.write_record(&cells)?;
    }
    w.flush()
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
///
/// Lines whose first non-blank character is `#` are comments (`# key = value` ones carry
/// metadata); blank lines are skipped; the first other line is the header. Cells are trimmed and
/// may be quoted.
pub(crate) fn parse_csv(text: &str, origin: &str) -> Result<(Series, Vec<usize>)> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut series = Series::default();
    // Comments first (blanked, so that the records keep their line numbers).
    let mut records = String::with_capacity(text.len());
    for line in text.lines() {
        match line.trim().strip_prefix('#') {
            Some(comment) => {
                if let Some((key, value)) = comment.split_once('=') {
                    if is_meta_key(key.trim()) {
                        series.set_meta(key.trim(), value.trim());
                    }
                }
            }
            None => records.push_str(line),
        }
        records.push('\n');
    }
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .trim(csv::Trim::All)
        .from_reader(records.as_bytes());
    let mut row_lines = Vec::new();
    let mut header = false;
    let mut record = csv::StringRecord::new();
    loop {
        match reader.read_record(&mut record) {
            Ok(true) => {}
            Ok(false) => break,
            Err(e) => {
                let line = e.position().map_or(0, |p| {
                    record_line(&records, p.byte() as usize, p.line() as usize)
                });
                return Err(Error::data(origin, line, format!("not a CSV record: {e}")));
            }
        }
        let line_no = record.position().map_or(0, |p| {
            record_line(&records, p.byte() as usize, p.line() as usize)
        });
        // A line of blanks only.
        if record.len() == 1 && record[0].is_empty() {
            continue;
        }
        // The first other line is the header.
        if !header {
            // One column whose name holds another separator: a file separated by it.
            if record.len() == 1 {
                if let Some(sep) = [';', '\t', '|']
                    .into_iter()
                    .find(|&c| record[0].contains(c))
                {
                    return Err(Error::data(
                        origin,
                        line_no,
                        format!(
                            "the header is one column, {:?}: the file seems separated by {sep:?}, \
                             and recordings are read as comma-separated values (`t,theta01,...`; \
                             `.` as the decimal point)",
                            &record[0]
                        ),
                    ));
                }
            }
            for (c, name) in record.iter().enumerate() {
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
        if record.len() != series.columns.len() {
            return Err(Error::data(
                origin,
                line_no,
                format!(
                    "{} values, but the header has {} columns",
                    record.len(),
                    series.columns.len()
                ),
            ));
        }
        for (c, cell) in record.iter().enumerate() {
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

/// The line of a record that the reader placed at `byte` and `line`: the reader counts from
/// where it began to scan, before the blank lines it skipped, so those are added.
fn record_line(text: &str, byte: usize, line: usize) -> usize {
    let skipped = text
        .as_bytes()
        .get(byte..)
        .unwrap_or_default()
        .iter()
        .take_while(|b| matches!(b, b'\n' | b'\r'))
        .filter(|&&b| b == b'\n')
        .count();
    line + skipped
}

/// A finite number or NaN.
fn parse_number(cell: &str) -> Option<f64> {
    cell.parse::<f64>().ok().filter(|x| !x.is_infinite())
}
