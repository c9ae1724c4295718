//! The `vibrissa` binary run as a user runs it.

use serde_json::Value;
use std::process::{Command, Output};

/// Runs the binary with `args` and returns its exit status and output.
fn vibrissa(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_vibrissa"))
        .args(args)
        .output()
        .expect("the vibrissa binary should start")
}

fn stdout(out: &Output) -> String {
    String::from_utf8(out.stdout.clone()).expect("stdout is UTF-8")
}

fn stderr(out: &Output) -> String {
    String::from_utf8(out.stderr.clone()).expect("stderr is UTF-8")
}

/// Parses standard output as one JSON value, showing both streams if it is not.
fn json(out: &Output) -> Value {
    serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!(
            "stdout is not JSON ({e}):\n{}\nstderr:\n{}",
            stdout(out),
            stderr(out)
        )
    })
}

/// A refused command line: non-zero exit, a message, no panic.
fn assert_refused(out: &Output) {
    let err = stderr(out);
    assert!(!out.status.success(), "should fail; stderr:\n{err}");
    assert!(
        !err.contains("panicked"),
        "should not panic; stderr:\n{err}"
    );
    assert!(
        err.contains("error"),
        "should say what is wrong; stderr:\n{err}"
    );
}

#[test]
fn help_lists_the_commands() {
    let out = vibrissa(&["--help"]);
    assert!(out.status.success());
    let text = stdout(&out);
    for command in ["validate", "bench"] {
        assert!(text.contains(command), "--help lacks {command}:\n{text}");
    }
}

#[test]
fn version_names_the_tool() {
    let out = vibrissa(&["--version"]);
    assert!(out.status.success());
    assert!(stdout(&out).starts_with("vibrissa "), "{}", stdout(&out));
}

#[test]
fn bench_quick_json_reports_positive_speeds() {
    let out = vibrissa(&["bench", "--quick", "--json"]);
    assert!(out.status.success(), "stderr:\n{}", stderr(&out));
    let report = json(&out);

    // The single-state figure at N = 20 is there and positive.
    let single = report["single"].as_array().expect("a `single` array");
    let n20 = single
        .iter()
        .find(|s| s["segments"] == 20)
        .expect("a single-state figure at N = 20");
    let rate = n20["steps_per_second"].as_f64().expect("steps_per_second");
    assert!(rate.is_finite() && rate > 0.0, "steps_per_second = {rate}");
    let per_step = n20["seconds_per_step"].as_f64().expect("seconds_per_step");
    assert!((rate * per_step - 1.0).abs() < 1e-9, "{n20}");

    // The batch and the thread count are reported.
    let threads = report["threads"].as_u64().expect("threads");
    assert!(threads >= 1);
    let batch = report["batch"]["state_steps_per_second"]
        .as_f64()
        .expect("batch.state_steps_per_second");
    assert!(batch.is_finite() && batch > 0.0, "{}", report["batch"]);
    assert!(report["scaling"]["ratio"].as_f64().expect("scaling.ratio") > 0.0);
}

#[test]
fn bench_quick_prints_a_table() {
    let out = vibrissa(&[
        "bench",
        "--quick",
        "--whisker",
        "robot",
        "--discretisation",
        "seed",
    ]);
    assert!(out.status.success(), "stderr:\n{}", stderr(&out));
    let text = stdout(&out);
    assert!(text.contains("whisker robot, seed stiffness"), "{text}");
    assert!(text.contains("steps/s"), "{text}");
    assert!(text.contains("speedup"), "{text}");
}

#[test]
fn validate_quick_json_has_checks() {
    let out = vibrissa(&["validate", "--quick", "--json"]);
    assert!(out.status.success(), "stderr:\n{}", stderr(&out));
    let report = json(&out);
    let checks = report["checks"].as_array().expect("a `checks` array");
    for check in checks {
        for field in ["group", "label", "quantity", "unit", "error_unit"] {
            assert!(check[field].is_string(), "{field} in {check}");
        }
        for field in ["value", "reference", "error"] {
            assert!(check[field].is_number(), "{field} in {check}");
        }
    }
}

#[test]
fn validate_quick_table_shows_every_group() {
    let json_out = vibrissa(&["validate", "--quick", "--json"]);
    assert!(json_out.status.success(), "stderr:\n{}", stderr(&json_out));
    let report = json(&json_out);
    let checks = report["checks"].as_array().expect("a `checks` array");

    let out = vibrissa(&["validate", "--quick"]);
    assert!(out.status.success(), "stderr:\n{}", stderr(&out));
    let text = stdout(&out);
    for check in checks {
        let group = check["group"].as_str().expect("group");
        assert!(text.contains(group), "table lacks group {group}:\n{text}");
    }
    assert!(
        text.contains(&format!("{} checks", checks.len())),
        "table lacks the summary:\n{text}"
    );
}

#[test]
fn unknown_subcommand_is_refused() {
    let out = vibrissa(&["simulte"]);
    assert_refused(&out);
    assert_eq!(out.status.code(), Some(2), "usage errors exit with 2");
}

#[test]
fn bad_flag_is_refused() {
    assert_refused(&vibrissa(&["bench", "--fast"]));
    assert_refused(&vibrissa(&["validate", "--quick=maybe"]));
}

#[test]
fn missing_subcommand_shows_usage() {
    let out = vibrissa(&[]);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "stderr:\n{err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(err.contains("Usage") && err.contains("validate"), "{err}");
}

#[test]
fn unknown_whisker_lists_the_presets() {
    let out = vibrissa(&["bench", "--whisker", "cat"]);
    assert_refused(&out);
    let err = stderr(&out);
    assert!(err.contains("whisker"), "{err}");
    for preset in ["w30", "rat", "robot"] {
        assert!(err.contains(preset), "{preset} missing from:\n{err}");
    }
}

#[test]
fn unknown_discretisation_lists_the_rules() {
    let out = vibrissa(&["bench", "--discretisation", "euler"]);
    assert_refused(&out);
    let err = stderr(&out);
    assert!(err.contains("discretisation"), "{err}");
    for rule in ["gregory", "trapezoid", "seed"] {
        assert!(err.contains(rule), "{rule} missing from:\n{err}");
    }
}
