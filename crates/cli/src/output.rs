//! How results reach the user: a table for people or JSON for programs, chosen once per run.
//!
//! A command builds one result value that implements [`Render`] (its human form) and
//! `serde::Serialize` (its JSON form), then hands it to [`Format::print`]. Progress and
//! diagnostics go to standard error, so standard output carries only the result.

use serde::Serialize;
use std::io::{self, Write};

/// Command-line flags that choose the output format (flattened into every subcommand).
#[derive(Debug, Clone, Copy, clap::Args)]
pub struct FormatArgs {
    /// Print the result as JSON on standard output (all quantities in SI units).
    #[arg(long)]
    pub json: bool,
}

impl FormatArgs {
    /// The chosen format.
    pub fn format(self) -> Format {
        if self.json {
            Format::Json
        } else {
            Format::Human
        }
    }
}

/// A command's result, printable for people; its JSON form comes from `Serialize`.
pub trait Render: Serialize {
    /// Writes the human-readable form (tables, headings) to `out`.
    fn render(&self, out: &mut dyn Write) -> io::Result<()>;
}

/// Output format of a run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// Aligned tables and short headings.
    Human,
    /// One pretty-printed JSON value.
    Json,
}

impl Format {
    /// Writes `value` in this format to `out`.
    pub fn write<T: Render + ?Sized>(self, value: &T, out: &mut dyn Write) -> io::Result<()> {
        match self {
            Format::Human => value.render(out)?,
            Format::Json => {
                serde_json::to_writer_pretty(&mut *out, value)?;
                writeln!(out)?;
            }
        }
        out.flush()
    }

    /// Writes `value` in this format to standard output.
    pub fn print<T: Render + ?Sized>(self, value: &T) -> io::Result<()> {
        let stdout = io::stdout();
        let mut out = stdout.lock();
        self.write(value, &mut out)
    }
}

/// Horizontal alignment of a table column.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Align {
    /// Text columns.
    Left,
    /// Number columns.
    Right,
}

/// A plain-text table with a header row, columns padded to their widest cell.
#[derive(Debug, Clone)]
pub struct Table {
    /// Column titles and alignments: `[columns]`.
    columns: Vec<(String, Align)>,
    /// Cells, row by row: `[rows][columns]`.
    rows: Vec<Vec<String>>,
}

impl Table {
    /// A table with the given column titles and alignments.
    pub fn new(columns: &[(&str, Align)]) -> Table {
        Table {
            columns: columns.iter().map(|&(t, a)| (t.to_string(), a)).collect(),
            rows: Vec::new(),
        }
    }

    /// Appends a row (missing cells are blank, extra cells are dropped).
    pub fn row(&mut self, cells: Vec<String>) {
        let mut cells = cells;
        cells.resize(self.columns.len(), String::new());
        self.rows.push(cells);
    }

    /// Writes the table, every line starting with `indent`.
    pub fn write(&self, out: &mut dyn Write, indent: &str) -> io::Result<()> {
        // Column widths in characters (units such as µs and N·m are multi-byte).
        let width = |s: &str| s.chars().count();
        let widths: Vec<usize> = (0..self.columns.len())
            .map(|c| {
                self.rows
                    .iter()
                    .map(|r| width(&r[c]))
                    .chain([width(&self.columns[c].0)])
                    .max()
                    .unwrap_or(0)
            })
            .collect();

        // One line: cells padded to their column, two spaces between columns.
        let line = |out: &mut dyn Write, cells: &[String]| -> io::Result<()> {
            let mut text = String::from(indent);
            for (c, cell) in cells.iter().enumerate() {
                let pad = " ".repeat(widths[c] - width(cell));
                if c > 0 {
                    text.push_str("  ");
                }
                match self.columns[c].1 {
                    Align::Left => {
                        text.push_str(cell);
                        text.push_str(&pad);
                    }
                    Align::Right => {
                        text.push_str(&pad);
                        text.push_str(cell);
                    }
                }
            }
            writeln!(out, "{}", text.trim_end())
        };

        // Header, a rule under it, then the rows.
        let header: Vec<String> = self.columns.iter().map(|(t, _)| t.clone()).collect();
        line(out, &header)?;
        let rule: Vec<String> = widths.iter().map(|&w| "-".repeat(w)).collect();
        line(out, &rule)?;
        for row in &self.rows {
            line(out, row)?;
        }
        Ok(())
    }
}

/// `x` with `digits` significant digits: fixed-point for magnitudes from 1e-3 to below 1e6,
/// scientific otherwise (`1.23e-5`).
pub fn sig(x: f64, digits: usize) -> String {
    if !x.is_finite() {
        return format!("{x}");
    }
    if x == 0.0 {
        return "0".to_string();
    }
    let digits = digits.max(1);
    let exponent = x.abs().log10().floor() as i32;
    if (-3..6).contains(&exponent) {
        let decimals = (digits as i32 - 1 - exponent).max(0) as usize;
        format!("{x:.decimals$}")
    } else {
        format!("{x:.*e}", digits - 1)
    }
}

/// A non-negative count or rate rounded to an integer, with thin groups of three digits
/// (`12 345 678`).
pub fn grouped(x: f64) -> String {
    if !x.is_finite() || x < 0.0 {
        return format!("{x}");
    }
    let digits = format!("{:.0}", x);
    let mut out = String::with_capacity(digits.len() + digits.len() / 3);
    for (i, ch) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i) % 3 == 0 {
            out.push(' ');
        }
        out.push(ch);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn significant_digits() {
        assert_eq!(sig(0.0, 3), "0");
        assert_eq!(sig(1.0, 3), "1.00");
        assert_eq!(sig(51.3412, 4), "51.34");
        assert_eq!(sig(-0.012345, 3), "-0.0123");
        assert_eq!(sig(2.3562e-7, 3), "2.36e-7");
        assert_eq!(sig(1.5e7, 2), "1.5e7");
        assert_eq!(sig(123456.0, 3), "123456");
    }

    #[test]
    fn thousands_groups() {
        assert_eq!(grouped(0.0), "0");
        assert_eq!(grouped(999.4), "999");
        assert_eq!(grouped(1000.0), "1 000");
        assert_eq!(grouped(12345678.0), "12 345 678");
    }

    #[test]
    fn table_pads_columns_by_characters() {
        let mut t = Table::new(&[("name", Align::Left), ("value", Align::Right)]);
        t.row(vec!["µs".into(), "1".into()]);
        t.row(vec!["long name".into(), "12345".into()]);
        let mut buf = Vec::new();
        t.write(&mut buf, "  ").unwrap();
        let text = String::from_utf8(buf).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], "  name       value");
        assert_eq!(lines[1], "  ---------  -----");
        assert_eq!(lines[2], "  µs             1");
        assert_eq!(lines[3], "  long name  12345");
    }
}
