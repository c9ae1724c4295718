//! `vibrissa calibrate` on labelled folders whose labels or rates are wrong: each is refused with
//! the file, the field and what is allowed named, and nothing is written.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn vibrissa(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_vibrissa"))
        .args(args)
        .output()
        .expect("the vibrissa binary should start")
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// A folder of its own for one test, removed when dropped.
struct Scratch(PathBuf);

impl Scratch {
    fn new(test: &str) -> Scratch {
        let dir =
            std::env::temp_dir().join(format!("vibrissa-cal-labels-{}-{test}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(dir.join("calib")).expect("a scratch folder");
        Scratch(dir)
    }

    fn calib(&self) -> PathBuf {
        self.0.join("calib")
    }

    fn out(&self) -> PathBuf {
        self.0.join("fitted.toml")
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = fs::remove_dir_all(&self.0);
    }
}

/// Short strikes keep the tests quick.
const SHORT: &str = "duration=0.08";

/// Simulates a clean `e2` strike at (d, v) with `sets` into `dir/name`.
fn strike(dir: &Path, name: &str, d: f64, v: f64, sets: &[&str]) {
    let out = dir.join(name).display().to_string();
    let (d, v) = (format!("d={d}"), format!("v={v}"));
    let mut args = vec!["simulate", "e2", "--set", SHORT, "--set", &d, "--set", &v];
    for s in sets {
        args.extend(["--set", s]);
    }
    args.extend(["--out", &out]);
    let run = vibrissa(&args);
    assert!(run.status.success(), "simulate: {}", stderr(&run));
}

/// Runs calibrate against e2 (short) on the scratch folder's `calib`.
fn calibrate(scratch: &Scratch) -> Output {
    let (dir, out) = (
        scratch.calib().display().to_string(),
        scratch.out().display().to_string(),
    );
    vibrissa(&[
        "calibrate",
        "--scenario",
        "e2",
        "--set",
        SHORT,
        "--labelled",
        &dir,
        "--out",
        &out,
    ])
}

/// A refusal: non-zero exit, no panic, a message holding every one of `words` and none of
/// `not`, no fitted file.
fn assert_refused(scratch: &Scratch, out: &Output, words: &[&str], not: &[&str]) {
    let err = stderr(out);
    assert!(!out.status.success(), "should fail; stderr:\n{err}");
    assert!(!err.contains("panicked"), "should not panic:\n{err}");
    for w in words {
        assert!(err.contains(w), "the message should name `{w}`:\n{err}");
    }
    for w in not {
        assert!(!err.contains(w), "the message should not say `{w}`:\n{err}");
    }
    assert!(!scratch.out().exists(), "nothing may be written on failure");
}

#[test]
fn a_truth_csv_without_a_column_for_an_unknown_is_refused() {
    let scratch = Scratch::new("unknown");
    let dir = scratch.calib();
    strike(&dir, "a.csv", 0.02, 0.5, &[]);
    strike(&dir, "b.csv", 0.025, 0.8, &[]);
    // e2's unknowns are d and v; v is left out.
    fs::write(dir.join("truth.csv"), "file,d\na.csv,0.02\nb.csv,0.025\n").unwrap();
    let out = calibrate(&scratch);
    assert_refused(
        &scratch,
        &out,
        &[
            "truth.csv: no column for the unknown `v`",
            "the scenario's unknowns are d, v",
            "label every one",
        ],
        &["start 1"],
    );
}

#[test]
fn a_recording_at_another_rate_is_named_with_its_rate_and_the_others() {
    let scratch = Scratch::new("rate");
    let dir = scratch.calib();
    strike(&dir, "a.csv", 0.02, 0.5, &[]);
    strike(&dir, "b.csv", 0.025, 0.8, &["sample_rate=500"]);
    fs::write(
        dir.join("truth.csv"),
        "file,d,v\na.csv,0.02,0.5\nb.csv,0.025,0.8\n",
    )
    .unwrap();
    let out = calibrate(&scratch);
    assert_refused(
        &scratch,
        &out,
        &[
            "b.csv: sampled at 500.000000 Hz",
            "a.csv, is at 1000.000000 Hz",
        ],
        &["666"],
    );
}

#[test]
fn a_label_out_of_range_is_named_with_its_row_and_what_is_allowed() {
    let scratch = Scratch::new("range");
    let dir = scratch.calib();
    strike(&dir, "a.csv", 0.02, 0.5, &[]);
    strike(&dir, "b.csv", 0.025, 0.8, &[]);
    for (truth, at) in [
        (
            "file,d,v\na.csv,-0.02,0.5\nb.csv,0.025,0.8\n",
            "truth.csv, line 2: `d` = -0.02 for `a.csv` is out of range",
        ),
        (
            "file,d,v\na.csv,0.02,0.5\nb.csv,-0.02,0.8\n",
            "truth.csv, line 3: `d` = -0.02 for `b.csv` is out of range",
        ),
    ] {
        fs::write(dir.join("truth.csv"), truth).unwrap();
        let out = calibrate(&scratch);
        assert_refused(
            &scratch,
            &out,
            &[at, "allowed is a distance from the base > 0 m"],
            &["names no key"],
        );
    }
}
