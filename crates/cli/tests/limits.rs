//! Requests no machine can meet, and settings that cannot work, are refused before anything runs:
//! counts beyond their limits, runs with too many steps or too few samples, an empty scenario
//! file, an export folder that cannot be made, too few particles for the whiskers entertained,
//! estimates that are not numbers, and names that mean nothing. Each refusal names the option or
//! key and what is allowed, exits non-zero and leaves nothing behind.

mod common;

use common::Scratch;
use std::fs;
use std::path::Path;
use std::process::{Command, Output};

fn vibrissa_in(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_vibrissa"))
        .current_dir(dir)
        .args(args)
        .output()
        .expect("the vibrissa binary should start")
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Commands run in a test's own folder.
trait InFolder {
    fn run(&self, args: &[&str]) -> Output;
    /// Simulates the default `e2` strike into `ok.csv` in the folder.
    fn strike(&self);
}

impl InFolder for Scratch {
    fn run(&self, args: &[&str]) -> Output {
        vibrissa_in(self, args)
    }

    fn strike(&self) {
        let out = self.run(&["simulate", "e2", "--out", "ok.csv"]);
        assert!(out.status.success(), "{}", stderr(&out));
    }
}

/// Asserts that `out` failed and that its standard error holds every one of `words`.
fn refused(out: &Output, words: &[&str]) {
    let err = stderr(out);
    assert!(!out.status.success(), "should fail; stderr: {err}");
    assert!(!err.contains("panicked"), "a panic: {err}");
    for w in words {
        assert!(err.contains(w), "`{w}` missing from: {err}");
    }
}

#[test]
fn counts_beyond_their_limits_are_refused_before_anything_is_made() {
    let s = Scratch::new("lim", "counts");
    let cases: [(&[&str], &[&str]); 8] = [
        (
            &[
                "experiment",
                "e3",
                "--training",
                "100000000000",
                "--runs",
                "1",
            ],
            &["--training", "1 to 20000"],
        ),
        (
            &[
                "experiment",
                "e3",
                "--training",
                "20",
                "--runs",
                "100000000000",
            ],
            &["--runs", "1 to 10000"],
        ),
        (
            &["experiment", "e1", "--particles", "10000000000"],
            &["--particles", "0 to 1000000"],
        ),
        (
            &[
                "estimate",
                "--experiment",
                "e2",
                "--obs",
                "x.csv",
                "--method",
                "pf",
                "--particles",
                "4294967296",
            ],
            &["--particles", "1 to 1000000"],
        ),
        (
            &[
                "estimate",
                "--experiment",
                "e2",
                "--obs",
                "x.csv",
                "--method",
                "pf",
                "--alternatives",
                "100000",
            ],
            &["--alternatives", "0 to 65534"],
        ),
        (
            &["bench", "--pf", "--quick", "--particles", "100,10000000000"],
            &["--particles", "1 to 1000000"],
        ),
        (
            &[
                "estimate",
                "--experiment",
                "e2",
                "--obs",
                "x.csv",
                "--method",
                "pf",
                "--islands",
                "0",
            ],
            &["--islands", "1 to 64"],
        ),
        (
            &["bench", "--pf", "--randomise", "--islands", "65"],
            &["--islands", "1 to 64"],
        ),
    ];
    for (args, words) in cases {
        refused(&s.run(args), words);
    }
    // Particle counts are measured by the filter's benchmark only.
    refused(&s.run(&["bench", "--particles", "100"]), &["--pf"]);
    assert!(s.entries().is_empty(), "left behind: {:?}", s.entries());
}

#[test]
fn runs_with_too_many_steps_or_too_few_samples_are_refused() {
    let s = Scratch::new("lim", "steps");
    let cases: [(&str, &[&str]); 3] = [
        ("dt=1e-12", &["dt", "2e8 steps"]),
        ("duration=100000", &["duration", "2e7 samples"]),
        ("sample_rate=1.5", &["duration", "at least two samples"]),
    ];
    for (set, words) in cases {
        let out = s.run(&["simulate", "e2", "--set", set, "--out", "r.csv"]);
        refused(&out, words);
    }
    assert!(s.entries().is_empty(), "left behind: {:?}", s.entries());
}

#[test]
fn an_empty_scenario_file_is_refused() {
    let s = Scratch::new("lim", "empty");
    for (name, text) in [("empty.toml", ""), ("comments.toml", "# nothing yet\n\n")] {
        fs::write(s.join(name), text).expect("a scenario file");
        let out = s.run(&["simulate", name, "--out", "r.csv"]);
        refused(&out, &[name, "empty", "experiment = \"e2\""]);
    }
    assert!(!s.join("r.csv").exists());
}

#[test]
fn an_export_folder_that_cannot_be_made_is_refused_before_the_experiment_runs() {
    let s = Scratch::new("lim", "export");
    fs::write(s.join("taken"), "a file").expect("a file");
    for export in ["taken", "taken/below"] {
        let out = s.run(&[
            "experiment",
            "e3",
            "--training",
            "20",
            "--runs",
            "1",
            "--out",
            "exp",
            "--export",
            export,
        ]);
        refused(&out, &["--export", "is a file"]);
    }
    assert_eq!(s.entries(), vec!["taken".to_string()]);
}

#[test]
fn settings_that_cannot_work_are_named() {
    let s = Scratch::new("lim", "settings");
    s.strike();
    // Fewer particles than the whiskers a randomised filter entertains.
    let out = s.run(&[
        "estimate",
        "--experiment",
        "e2",
        "--obs",
        "ok.csv",
        "--method",
        "pf",
        "--randomise",
        "--particles",
        "50",
    ]);
    refused(
        &out,
        &["--particles 50", "--alternatives 63", "64 whiskers"],
    );
    // A lead-in that is not a whole number of samples.
    let out = s.run(&["experiment", "e1", "--max-delay", "0.0005", "--out", "exp"]);
    refused(&out, &["--max-delay", "whole number of milliseconds"]);
    assert!(!s.join("exp").exists());
}

#[test]
fn an_estimate_that_is_not_a_number_is_refused_not_printed() {
    let s = Scratch::new("lim", "nan");
    s.strike();
    // A stated noise so large that every template is equally (im)probable.
    let out = s.run(&[
        "estimate",
        "--experiment",
        "e2",
        "--method",
        "template",
        "--obs",
        "ok.csv",
        "--noise",
        "theta12=1e300",
        "--json",
    ]);
    refused(&out, &["template could not estimate", "ok.csv", "theta12"]);
    assert!(
        out.stdout.is_empty(),
        "printed: {}",
        String::from_utf8_lossy(&out.stdout)
    );
    // The line on where the noise came from says which levels were stated.
    let out = s.run(&[
        "estimate",
        "--experiment",
        "e2",
        "--method",
        "knn",
        "--obs",
        "ok.csv",
        "--noise",
        "theta12=1e-5",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("theta12 as stated"),
        "{}",
        stderr(&out)
    );
}

#[test]
fn priors_outside_what_the_filter_can_tell_apart_are_refused_by_name() {
    let s = Scratch::new("lim", "priors");
    s.strike();
    let filter = |prior: &str| {
        s.run(&[
            "estimate",
            "--experiment",
            "e2",
            "--obs",
            "ok.csv",
            "--method",
            "pf",
            "--particles",
            "50",
            "--prior",
            prior,
        ])
    };
    refused(&filter("d=-0.1:0.03"), &["--prior `d=-0.1:0.03`", "[0, ∞)"]);
    refused(&filter("v=0.1:1e6"), &["--prior `v=0.1:1e6`", "50]"]);
    refused(&filter("mu=0:11"), &["mu", "[0, 10]"]);
    // Beyond the tip no box touches the whisker.
    refused(
        &filter("d=0:1e9"),
        &["--prior d=0:1000000000", "whisker's length (0.03 m)"],
    );
}

#[test]
fn a_wrong_name_is_answered_with_what_exists() {
    let s = Scratch::new("lim", "names");
    s.strike();
    let out = s.run(&[
        "estimate",
        "--shapes",
        "e9",
        "--method",
        "shape-krr",
        "--obs",
        "ok.csv",
    ]);
    refused(&out, &["no shape family `e9`", "e3, e3-active"]);
    // A file where the output folder of an experiment is expected.
    let out = s.run(&["report", "ok.csv"]);
    refused(&out, &["`ok.csv` is a file", "--out DIR"]);
}

#[test]
fn a_table_or_a_number_given_in_the_wrong_form_is_answered_with_its_form() {
    let s = Scratch::new("lim", "forms");
    let cases: [(&str, &[&str]); 6] = [
        (
            "whisker.damping.ratio=-0.5",
            &["whisker.damping", "kind = \"modal_ratio\""],
        ),
        (
            "whisker.damping=-1",
            &["whisker.damping", "give the whole table"],
        ),
        (
            "whisker.follicle.stiffness=-2",
            &["kind = \"spring\", stiffness"],
        ),
        ("duration=NaN", &["duration", "a number is expected here"]),
        // e2's box comes from d and v: an object key makes a new object of that one key.
        (
            "objects.0.radius=0.002",
            &["`shape`", "whose box comes from `d` and `v`"],
        ),
        (
            "objects.radius=0.002",
            &["array of tables", "objects.0.friction"],
        ),
    ];
    for (set, words) in cases {
        refused(
            &s.run(&["simulate", "e2", "--set", set, "--out", "r.csv"]),
            words,
        );
    }
    assert!(s.entries().is_empty(), "left behind: {:?}", s.entries());
}
