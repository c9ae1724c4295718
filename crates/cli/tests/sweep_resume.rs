//! `vibrissa sweep`: the limit on a grid's size, and resuming a folder only with the settings its
//! runs were made with.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs the binary with `args`.
fn vibrissa(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_vibrissa"))
        .args(args)
        .output()
        .expect("the vibrissa binary should start")
}

fn stdout(out: &Output) -> String {
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Asserts a run that succeeded.
fn assert_ok(out: &Output) {
    assert!(
        out.status.success(),
        "stdout:\n{}\nstderr:\n{}",
        stdout(out),
        stderr(out)
    );
}

/// Asserts a refusal: exit status 1, a message on standard error, nothing on standard output.
fn assert_refused(out: &Output) {
    assert_eq!(out.status.code(), Some(1), "stderr:\n{}", stderr(out));
    assert!(stderr(out).starts_with("error: "), "{}", stderr(out));
    assert!(stdout(out).is_empty(), "{}", stdout(out));
}

/// An empty folder of its own for one test, removed when dropped.
struct Scratch(PathBuf);

impl Scratch {
    fn new(test: &str) -> Scratch {
        let dir = std::env::temp_dir().join(format!(
            "vibrissa-sweep-resume-{}-{test}",
            std::process::id()
        ));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).expect("a scratch folder");
        Scratch(dir)
    }

    fn path(&self) -> &Path {
        &self.0
    }

    /// The scenario (see [`Scratch::scenario`]) and the folder `runs` holding its sweep of one
    /// run, `--grid objects.0.radius=0.002`.
    fn one_run(&self) -> (String, PathBuf) {
        let scenario = self.scenario();
        let dir = self.0.join("runs");
        assert_ok(&sweep(
            &scenario,
            &dir,
            &["--grid", "objects.0.radius=0.002"],
        ));
        (scenario, dir)
    }

    /// A copy of the example scenario `peg_past.toml` in the folder; its path.
    fn scenario(&self) -> String {
        let example =
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/scenarios/peg_past.toml");
        let copy = self.0.join("peg_past.toml");
        fs::copy(example, &copy).expect("the example scenario");
        copy.to_str().unwrap().to_string()
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = fs::remove_dir_all(&self.0);
    }
}

/// Names of the entries of `dir` (hidden ones included), sorted.
fn entries(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = fs::read_dir(dir)
        .expect("a readable folder")
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// Every file of `dir` with its bytes, sorted by name.
fn contents(dir: &Path) -> Vec<(String, Vec<u8>)> {
    entries(dir)
        .into_iter()
        .map(|name| {
            let bytes = fs::read(dir.join(&name)).unwrap();
            (name, bytes)
        })
        .collect()
}

/// A sweep of `scenario` into `dir`, 10 ms long, with the extra arguments `rest`.
fn sweep(scenario: &str, dir: &Path, rest: &[&str]) -> Output {
    let mut args = vec![
        "sweep",
        scenario,
        "--out",
        dir.to_str().unwrap(),
        "--set",
        "duration=0.01",
        "--jobs",
        "1",
        "--json",
    ];
    args.extend_from_slice(rest);
    vibrissa(&args)
}

/// `ran` and `skipped` of a sweep's JSON report.
fn ran_skipped(out: &Output) -> (u64, u64) {
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).expect("a JSON report");
    (
        report["ran"].as_u64().unwrap(),
        report["skipped"].as_u64().unwrap(),
    )
}

/// Asserts a refusal to resume `dir` that names `what` and suggests another folder.
fn assert_refused_folder(out: &Output, what: &str) {
    assert_refused(out);
    let err = stderr(out);
    assert!(err.contains("holds runs of another sweep"), "{err}");
    assert!(err.contains(what), "{err}");
    assert!(err.contains("another --out folder"), "{err}");
}

#[test]
fn a_range_over_the_maximum_is_refused_before_anything_is_made() {
    let scratch = Scratch::new("range");
    let dir = scratch.path().join("runs");
    let out = vibrissa(&[
        "sweep",
        "e2",
        "--out",
        dir.to_str().unwrap(),
        "--grid",
        "d=0.015:0.03:1000000000000",
    ]);
    assert_refused(&out);
    let err = stderr(&out);
    assert!(err.contains("--grid `d=0.015:0.03:1000000000000`"), "{err}");
    assert!(err.contains("1 000 000 000 000 values"), "{err}");
    assert!(err.contains("at most 1 000 000 runs"), "{err}");
    assert!(!dir.exists(), "no folder for a sweep that cannot run");
}

#[test]
fn grids_over_the_maximum_together_are_refused() {
    let scratch = Scratch::new("product");
    let dir = scratch.path().join("runs");
    // A value too long for a file name as well: a sweep that made the runs' names before
    // checking their number would stop there, with another message.
    let long = format!("whisker.length=0.03{}", "0".repeat(200));
    let out = vibrissa(&[
        "sweep",
        "e2",
        "--out",
        dir.to_str().unwrap(),
        "--grid",
        "d=0.015:0.03:1001",
        "--grid",
        "v=0.3:1.5:1000",
        "--grid",
        &long,
    ]);
    assert_refused(&out);
    let err = stderr(&out);
    assert!(err.contains("--grid: 1 001 000 runs in all"), "{err}");
    assert!(
        err.contains("d 1 001 × v 1 000 × whisker.length 1"),
        "{err}"
    );
    assert!(err.contains("at most 1 000 000 runs"), "{err}");
    assert!(!dir.exists(), "no folder for a sweep that cannot run");
}

#[test]
fn the_same_sweep_resumes_and_grows() {
    let scratch = Scratch::new("same");
    let scenario = scratch.scenario();
    let dir = scratch.path().join("runs");
    let out = sweep(&scenario, &dir, &["--grid", "objects.0.radius=0.002"]);
    assert_ok(&out);
    assert_eq!(ran_skipped(&out), (1, 0));
    let record = fs::read_to_string(dir.join(".sweep.json")).expect("the sweep's settings");
    assert!(record.contains("\"duration=0.01\""), "{record}");
    assert!(record.contains("\"objects.0.radius\""), "{record}");

    let out = sweep(&scenario, &dir, &["--grid", "objects.0.radius=0.002"]);
    assert_ok(&out);
    assert_eq!(ran_skipped(&out), (0, 1));
    assert!(!stderr(&out).contains("warning"), "{}", stderr(&out));

    // New values of the same key run; the finished one is skipped.
    let out = sweep(&scenario, &dir, &["--grid", "objects.0.radius=0.002,0.003"]);
    assert_ok(&out);
    assert_eq!(ran_skipped(&out), (1, 1));
    let manifest = fs::read_to_string(dir.join("manifest.csv")).unwrap();
    assert_eq!(manifest.lines().count(), 3, "{manifest}");
}

#[test]
fn other_set_values_are_refused() {
    let scratch = Scratch::new("set");
    let (scenario, dir) = scratch.one_run();
    let before = contents(&dir);

    let out = sweep(
        &scenario,
        &dir,
        &[
            "--set",
            "whisker.length=0.045",
            "--grid",
            "objects.0.radius=0.002",
        ],
    );
    assert_refused_folder(&out, "whisker.length=0.045");
    assert!(stderr(&out).contains("--set"), "{}", stderr(&out));
    assert_eq!(contents(&dir), before, "the folder is left as it was");
}

#[test]
fn another_scenario_or_other_keys_are_refused() {
    let scratch = Scratch::new("scenario");
    let (scenario, dir) = scratch.one_run();
    let before = contents(&dir);

    // A built-in experiment, its own key: the manifest would have lost the earlier run.
    let out = sweep("e2", &dir, &["--grid", "d=0.02"]);
    assert_refused_folder(&out, "`e2`");
    assert!(
        stderr(&out).contains("this sweep varies `d`"),
        "{}",
        stderr(&out)
    );
    assert_eq!(contents(&dir), before);

    // The same scenario, another key.
    let out = sweep(&scenario, &dir, &["--grid", "objects.0.friction=0.2"]);
    assert_refused_folder(&out, "this sweep varies `objects.0.friction`");
    assert_eq!(contents(&dir), before);
}

#[test]
fn an_edited_scenario_file_is_refused() {
    let scratch = Scratch::new("edited");
    let (scenario, dir) = scratch.one_run();
    let before = contents(&dir);

    // A comment does not change the scenario; a value does.
    let text = fs::read_to_string(&scenario).unwrap();
    fs::write(&scenario, format!("# the same peg\n{text}")).unwrap();
    let out = sweep(&scenario, &dir, &["--grid", "objects.0.radius=0.002"]);
    assert_ok(&out);
    assert_eq!(ran_skipped(&out), (0, 1));
    fs::write(
        &scenario,
        text.replace("preset = \"w30\"", "preset = \"rat\""),
    )
    .unwrap();
    let out = sweep(&scenario, &dir, &["--grid", "objects.0.radius=0.002"]);
    assert_refused_folder(&out, "has changed");
    assert_eq!(contents(&dir), before);
}

#[test]
fn a_folder_without_the_settings_file_is_checked_by_its_sidecars() {
    let scratch = Scratch::new("unrecorded");
    let (scenario, dir) = scratch.one_run();
    // As an earlier version, or the Python package, leaves it.
    let _ = fs::remove_file(dir.join(".sweep.json"));
    let before = contents(&dir);

    // The same settings: resumed, with a warning.
    let out = sweep(&scenario, &dir, &["--grid", "objects.0.radius=0.002"]);
    assert_ok(&out);
    assert_eq!(ran_skipped(&out), (0, 1));
    assert!(stderr(&out).contains("warning"), "{}", stderr(&out));
    assert_eq!(contents(&dir), before);

    // Other --set values, on the same run or on another.
    for radius in ["objects.0.radius=0.002", "objects.0.radius=0.003"] {
        let out = sweep(
            &scenario,
            &dir,
            &["--set", "whisker.length=0.045", "--grid", radius],
        );
        assert_refused_folder(&out, "whisker.length=0.045");
        assert_eq!(contents(&dir), before);
    }

    // Another scenario file with the same key.
    let other = scratch.path().join("other.toml");
    fs::copy(&scenario, &other).unwrap();
    let out = sweep(
        other.to_str().unwrap(),
        &dir,
        &["--grid", "objects.0.radius=0.002,0.003"],
    );
    assert_refused_folder(&out, "other.toml");
    assert_eq!(contents(&dir), before);
}

#[test]
fn a_built_in_experiment_resumes_and_refuses_other_settings() {
    let scratch = Scratch::new("builtin");
    let dir = scratch.path().join("runs");
    assert_ok(&sweep("e2", &dir, &["--grid", "d=0.02"]));
    assert_eq!(
        entries(&dir),
        ["d0.02.csv", "d0.02.json", "manifest.csv"],
        "a built-in experiment's folder holds its runs and the manifest only"
    );
    let out = sweep("e2", &dir, &["--grid", "d=0.02"]);
    assert_ok(&out);
    assert_eq!(ran_skipped(&out), (0, 1));
    let before = contents(&dir);

    let out = sweep("e1", &dir, &["--grid", "d=0.02"]);
    assert_refused_folder(&out, "`e1`");
    let out = sweep("e2", &dir, &["--set", "v=0.5", "--grid", "d=0.03"]);
    assert_refused_folder(&out, "v=0.5");
    assert_eq!(contents(&dir), before);
}
