//! `vibrissa validate`: the segment chain measured against continuum beam theory.

use crate::output::{sig, Align, FormatArgs, Render, Table};
use anyhow::{bail, Context, Result};
use std::io::{self, Write};
use vibrissa_core::validate::{self, Check, Report, ValidateOptions};

/// Arguments of `vibrissa validate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    format: FormatArgs,
    /// Fewer segment counts and shorter runs: a smoke test of the suite, not its figures.
    #[arg(long)]
    quick: bool,
}

/// Runs the suite, prints the report, and fails if any check with a target failed.
pub fn run(args: &Args) -> Result<()> {
    // Run the suite, with its progress on standard error.
    let opts = ValidateOptions { quick: args.quick };
    let report = validate::run(&opts, &mut |line: &str| eprintln!("{line}"))
        .context("the validation suite could not be completed")?;

    // Print the report, then turn failed checks into the exit status.
    args.format.format().print(&report)?;
    let failed: Vec<&Check> = report
        .checks
        .iter()
        .filter(|c| c.pass == Some(false))
        .collect();
    if !report.all_pass() {
        let names: Vec<String> = failed
            .iter()
            .map(|c| format!("{} / {} / {}", c.group, c.label, c.quantity))
            .collect();
        bail!(
            "{} of {} checks failed their target:\n  {}",
            failed.len(),
            report.checks.len(),
            names.join("\n  ")
        );
    }
    Ok(())
}

impl Render for Report {
    fn render(&self, out: &mut dyn Write) -> io::Result<()> {
        // Groups in the order the suite first ran them.
        let mut groups: Vec<&str> = Vec::new();
        for c in &self.checks {
            if !groups.contains(&c.group.as_str()) {
                groups.push(&c.group);
            }
        }

        // One table per group.
        for group in &groups {
            writeln!(out, "{group}")?;
            let mut table = Table::new(&[
                ("run", Align::Left),
                ("quantity", Align::Left),
                ("value", Align::Right),
                ("reference", Align::Right),
                ("unit", Align::Left),
                ("error", Align::Right),
                ("target", Align::Right),
                ("result", Align::Left),
            ]);
            for c in self.checks.iter().filter(|c| c.group == *group) {
                table.row(vec![
                    c.label.clone(),
                    c.quantity.clone(),
                    sig(c.value, 6),
                    sig(c.reference, 6),
                    if dimensionless(&c.unit) {
                        "-".to_string()
                    } else {
                        c.unit.clone()
                    },
                    error_text(c, c.error, true),
                    c.target
                        .map(|t| format!("≤ {}", error_text(c, t, false)))
                        .unwrap_or_else(|| "-".into()),
                    match c.pass {
                        Some(true) => "PASS",
                        Some(false) => "FAIL",
                        None => "-",
                    }
                    .to_string(),
                ]);
            }
            table.write(out, "  ")?;
            writeln!(out)?;
        }

        // A one-line summary.
        let targeted = self.checks.iter().filter(|c| c.pass.is_some()).count();
        let passed = self.checks.iter().filter(|c| c.pass == Some(true)).count();
        writeln!(
            out,
            "{} checks, {} with a requirement: {} pass, {} fail",
            self.checks.len(),
            targeted,
            passed,
            targeted - passed
        )
    }
}

/// An error (or a target on it) in the check's error unit: relative errors and fractions of the
/// whisker length as percentages, absolute errors in the quantity's unit.
fn error_text(c: &Check, e: f64, signed: bool) -> String {
    let number = |x: f64| {
        let s = sig(x, 3);
        if signed && x > 0.0 {
            format!("+{s}")
        } else {
            s
        }
    };
    match c.error_unit.as_str() {
        "relative" => format!("{} %", number(100.0 * e)),
        "fraction_of_length" => format!("{} % L", number(100.0 * e)),
        "absolute" if dimensionless(&c.unit) => number(e),
        "absolute" => format!("{} {}", number(e), c.unit),
        other => format!("{} {}", number(e), other),
    }
}

/// Whether `unit` is that of a pure number (`1` or empty).
fn dimensionless(unit: &str) -> bool {
    matches!(unit.trim(), "" | "1")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check(group: &str, error_unit: &str, error: f64, pass: Option<bool>) -> Check {
        Check {
            group: group.into(),
            label: "w30 gregory N=20".into(),
            quantity: "tip deflection".into(),
            unit: "m".into(),
            value: 3.0e-4,
            reference: 3.0e-4 * (1.0 + error),
            error,
            error_unit: error_unit.into(),
            target: pass.map(|_| 0.01),
            pass,
        }
    }

    #[test]
    fn table_groups_checks_and_marks_results() {
        let report = Report {
            checks: vec![
                check("static_small", "relative", -2.5e-3, Some(true)),
                check("frequency", "relative", 0.05, Some(false)),
                check("static_small", "fraction_of_length", 1e-4, None),
                Check {
                    unit: "1".into(),
                    ..check("stability", "absolute", 2.5e-6, Some(true))
                },
            ],
        };
        let mut buf = Vec::new();
        report.render(&mut buf).unwrap();
        let text = String::from_utf8(buf).unwrap();
        // Each group is one heading, in first-seen order, holding its own checks.
        let first = text.find("static_small").unwrap();
        let second = text.find("frequency").unwrap();
        assert!(first < second, "{text}");
        assert_eq!(text.matches("static_small").count(), 1, "{text}");
        assert!(text.contains("-0.250 %"), "{text}");
        assert!(text.contains("+0.0100 % L"), "{text}");
        assert!(text.contains("≤ 1.00 %"), "{text}");
        assert!(text.contains("PASS") && text.contains("FAIL"), "{text}");
        // A pure number shows no unit after its error.
        assert!(text.contains("+2.50e-6  ≤ 0.0100  PASS"), "{text}");
        assert!(
            text.contains("4 checks, 3 with a requirement: 2 pass, 1 fail"),
            "{text}"
        );
    }
}
