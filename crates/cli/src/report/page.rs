//! The report's HTML: the page template (an asset file) filled with the experiment's tables,
//! its figures (SVG inline, or PNG as `data:` URIs) and the runs' data as JSON, with its style
//! and script inline, so the page needs nothing but itself.

use super::results::{Num, Results};
use anyhow::{bail, Result};
use std::fmt::Write;
use std::path::Path;

/// The page, with `{{…}}` slots.
const TEMPLATE: &str = include_str!("template.html");
/// Its style sheet.
const STYLE: &str = include_str!("report.css");
/// Its script: the animation, the time series and the particle cloud.
const SCRIPT: &str = include_str!("report.js");

/// The experiment's figures, in the order the page shows them (any others follow, by name).
const FIGURES: [&str; 5] = [
    "templates",
    "responsibilities",
    "estimated-d",
    "estimated-v",
    "pf_calibration",
];

/// The whole page: `results` with the figures found in `dir` and the runs' JSON `data`.
pub fn render(results: &Results, dir: &Path, data: &str, note: &str) -> Result<String> {
    let title = format!(
        "experiment {} ({}), seed {}",
        results.family, results.variant, results.seed
    );
    let values = [
        ("TITLE", escape(&title)),
        ("VERSION", escape(env!("CARGO_PKG_VERSION"))),
        ("STYLE", STYLE.to_string()),
        ("SUMMARY", summary(results)),
        ("TABLE", table(results)),
        ("FIGURES", figures(dir)?),
        ("NOTE", escape(note)),
        ("DATA", script_safe(data)),
        ("SCRIPT", SCRIPT.to_string()),
    ];
    fill(TEMPLATE, &values)
}

/// `template` with every `{{NAME}}` replaced by its value, in one pass (a value is never read
/// for slots); a slot without a value is an error.
fn fill(template: &str, values: &[(&str, String)]) -> Result<String> {
    let mut out =
        String::with_capacity(template.len() + values.iter().map(|v| v.1.len()).sum::<usize>());
    let mut rest = template;
    while let Some(open) = rest.find("{{") {
        out.push_str(&rest[..open]);
        let after = &rest[open + 2..];
        let Some(close) = after.find("}}") else {
            bail!("the report template has an unclosed slot");
        };
        let name = &after[..close];
        match values.iter().find(|(n, _)| *n == name) {
            Some((_, v)) => out.push_str(v),
            None => bail!("the report template's slot {{{{{name}}}}} has no value"),
        }
        rest = &after[close + 2..];
    }
    out.push_str(rest);
    Ok(out)
}

/// Text made safe for HTML.
pub fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

/// JSON made safe inside a `<script>` element: no `</` can end it early.
fn script_safe(json: &str) -> String {
    json.replace("</", "<\\/").replace("<!--", "<\\!--")
}

/// The lines above the table: runs, noise.
fn summary(r: &Results) -> String {
    let templates = r.is_template.iter().filter(|t| **t).count();
    let sig = |x: &Num| crate::output::sig(x.0, 3);
    let list = |n: &[Num]| n.iter().map(sig).collect::<Vec<_>>().join(", ");
    let mut s = String::new();
    let _ = writeln!(
        s,
        "<p>{} runs, {} evaluated, {} templates; template σ² = {} rad²; wall time {} s.</p>",
        r.grid.len(),
        r.grid.len() - templates,
        templates,
        sig(&r.sigma2),
        sig(&r.seconds)
    );
    let _ = writeln!(
        s,
        "<p>Recordings made with sensor σ = [{}] (theta01, theta12 rad; m0 N·m; fx, fy N), process {} N·s<sup>½</sup>·m<sup>-½</sup>; the estimators measured σ = [{}] on them.</p>",
        list(&r.noise.sensor),
        sig(&r.noise.process),
        list(&r.estimated_noise.sensor)
    );
    if !r.sets.is_empty() {
        let _ = writeln!(
            s,
            "<p>Overrides: <code>{}</code></p>",
            escape(&r.sets.join(" "))
        );
    }
    s
}

/// The methods' errors and coverage beside the paper's figures, as `vibrissa experiment`
/// prints them.
fn table(r: &Results) -> String {
    let two = r.unknowns.len() == 2;
    let mut head = vec!["method", "budget", "training runs", "MAE d (mm)"];
    if two {
        head.push("MAE v (mm/ms)");
    }
    head.push("90% cover d");
    if two {
        head.push("90% cover v");
    }
    head.extend(["simulate (s)", "fit (s)", "estimate (ms)"]);
    let mut s = String::from("<table class=\"methods\">\n<thead><tr>");
    for h in &head {
        let _ = write!(s, "<th>{}</th>", escape(h));
    }
    s.push_str("</tr></thead>\n<tbody>\n");
    let row = |s: &mut String, cells: Vec<String>, class: &str| {
        let _ = write!(s, "<tr class=\"{class}\">");
        for c in cells {
            let _ = write!(s, "<td>{}</td>", escape(&c));
        }
        s.push_str("</tr>\n");
    };
    if let [d, rest @ ..] = &r.paper_mae[..] {
        let mut cells = vec![
            "paper (seed)".to_string(),
            "paper".into(),
            String::new(),
            format!("{:.2}", d.0 * 1e3),
        ];
        if let (true, Some(v)) = (two, rest.first()) {
            cells.push(format!("{:.3}", v.0));
        }
        cells.resize(head.len(), String::new());
        row(&mut s, cells, "paper");
    }
    for m in &r.methods {
        let mut cells = vec![
            m.name.clone(),
            m.budget.clone(),
            m.training_runs.to_string(),
            format!("{:.3}", m.mae[0].0 * 1e3),
        ];
        if two {
            cells.push(format!("{:.4}", m.mae[1].0));
        }
        cells.push(format!("{:.0}%", m.coverage[0].0 * 100.0));
        if two {
            cells.push(format!("{:.0}%", m.coverage[1].0 * 100.0));
        }
        cells.push(format!("{:.2}", m.simulate_seconds.0));
        cells.push(format!("{:.3}", m.fit_seconds.0));
        cells.push(format!("{:.3}", m.predict_seconds.0 * 1e3));
        row(&mut s, cells, "");
    }
    s.push_str("</tbody>\n</table>\n");
    for m in &r.methods {
        if let (Some(steps), Some(diverged), Some(refused)) = (
            m.setting("particle_steps"),
            m.setting("diverged_steps"),
            m.setting("refused_moves"),
        ) {
            let _ = writeln!(
                s,
                "<p>{}: {steps:.0} particle steps, {diverged:.0} diverged; {refused:.0} moves undone (a moved box the whisker could not follow).</p>",
                escape(&m.name)
            );
        }
    }
    s
}

/// Every figure in `dir`: its SVG inline when there is one, else its PNG as a `data:` URI.
fn figures(dir: &Path) -> Result<String> {
    let mut names: Vec<String> = Vec::new();
    for entry in std::fs::read_dir(dir)? {
        let path = entry?.path();
        let ext = crate::files::extension(&path);
        if matches!(ext.as_deref(), Some("svg" | "png")) {
            if let Some(stem) = path.file_stem().and_then(|s| s.to_str()) {
                if !stem.starts_with('.') && !names.iter().any(|n| n == stem) {
                    names.push(stem.to_string());
                }
            }
        }
    }
    let rank = |n: &str| {
        FIGURES
            .iter()
            .position(|f| *f == n)
            .unwrap_or(FIGURES.len())
    };
    names.sort_by(|a, b| rank(a).cmp(&rank(b)).then(a.cmp(b)));
    let mut s = String::new();
    for name in &names {
        let svg = dir.join(format!("{name}.svg"));
        let png = dir.join(format!("{name}.png"));
        let body = if svg.is_file() {
            let text = std::fs::read_to_string(&svg)?;
            match text.find("<svg") {
                Some(start) if !text.contains("<script") => text[start..].to_string(),
                _ => continue,
            }
        } else {
            let bytes = std::fs::read(&png)?;
            format!(
                "<img alt=\"{}\" src=\"data:image/png;base64,{}\">",
                escape(name),
                base64(&bytes)
            )
        };
        let _ = writeln!(
            s,
            "<figure id=\"figure-{0}\">{body}<figcaption>{0}</figcaption></figure>",
            escape(name)
        );
    }
    if s.is_empty() {
        s.push_str("<p>No figures in the folder.</p>\n");
    }
    Ok(s)
}

/// Standard base64 with padding.
pub fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            chunk.get(1).copied().unwrap_or(0),
            chunk.get(2).copied().unwrap_or(0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(ALPHABET[((n >> (18 - 6 * k)) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_the_standard() {
        assert_eq!(base64(b""), "");
        assert_eq!(base64(b"f"), "Zg==");
        assert_eq!(base64(b"fo"), "Zm8=");
        assert_eq!(base64(b"foo"), "Zm9v");
        assert_eq!(base64(b"foobar"), "Zm9vYmFy");
        assert_eq!(base64(&[0xff, 0xfe, 0x00]), "//4A");
    }

    #[test]
    fn text_and_json_cannot_break_out_of_their_elements() {
        assert_eq!(
            escape("<a href=\"x\">&'"),
            "&lt;a href=&quot;x&quot;&gt;&amp;&#39;"
        );
        let json = r#"{"label":"</script><script>alert(1)</script>"}"#;
        assert!(!script_safe(json).contains("</script"));
    }

    #[test]
    fn slots_are_filled_in_one_pass() {
        let values = [("A", "{{B}}".to_string()), ("B", "b".to_string())];
        assert_eq!(fill("x{{A}}y{{B}}{{A}}", &values).unwrap(), "x{{B}}yb{{B}}");
        assert!(fill("{{C}}", &values)
            .unwrap_err()
            .to_string()
            .contains("{{C}}"));
        assert!(fill("{{A", &values).is_err());
        // The template's own slots all have values.
        for slot in [
            "TITLE", "STYLE", "SUMMARY", "TABLE", "FIGURES", "NOTE", "DATA", "SCRIPT",
        ] {
            assert!(TEMPLATE.contains(&format!("{{{{{slot}}}}}")), "{slot}");
        }
    }
}
