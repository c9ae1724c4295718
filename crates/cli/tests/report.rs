//! `vibrissa report`, `vibrissa experiment --report` and `vibrissa simulate --animate` run as a
//! user runs them.

mod common;

use common::Scratch;
use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::OnceLock;

fn vibrissa() -> Command {
    Command::new(env!("CARGO_BIN_EXE_vibrissa"))
}

fn temp(name: &str) -> Scratch {
    Scratch::new("report", name)
}

fn ok(out: &Output) -> String {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// The error of a command that must fail with status 1.
fn failed(out: &Output) -> String {
    assert_eq!(
        out.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// The names in `dir`, sorted.
fn listing(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// One e2 experiment with a small particle filter and its report, shared by the tests. A
/// static is never dropped, so it lives in cargo's folder for the tests' temporary files,
/// under one name that every run replaces.
fn experiment() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("report-e2");
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).unwrap();
        let out = vibrissa()
            .args(["experiment", "e2", "--particles", "24", "--report", "--out"])
            .arg(&dir)
            .output()
            .unwrap();
        ok(&out);
        dir
    })
}

/// The page's embedded data.
fn page_data(html: &str) -> serde_json::Value {
    let open = r#"<script type="application/json" id="vibrissa-data">"#;
    let start = html.find(open).expect("the data element") + open.len();
    let end = start + html[start..].find("</script>").expect("its end");
    serde_json::from_str(&html[start..end]).expect("the data is JSON")
}

/// Every reference a page makes to something outside itself.
fn external_references(html: &str) -> Vec<String> {
    let lower = html.to_ascii_lowercase();
    let mut found = Vec::new();
    for attr in ["src=", "href=", "url(", "@import", "srcset="] {
        let mut from = 0;
        while let Some(k) = lower[from..].find(attr) {
            let at = from + k + attr.len();
            let value = lower[at..].trim_start_matches(['"', '\'', ' ']);
            if !value.starts_with("data:") && !value.starts_with('#') {
                found.push(lower[from + k..(at + 40).min(lower.len())].to_string());
            }
            from = at;
        }
    }
    for tag in ["<link", "<iframe", "<object", "<embed"] {
        if lower.contains(tag) {
            found.push(tag.to_string());
        }
    }
    found
}

/// The page's recording of run `k` is the experiment's (theta12, to the digits the page keeps).
fn assert_recording_is_the_experiment_s(
    run: &serde_json::Value,
    results: &serde_json::Value,
    k: usize,
) {
    for (a, b) in run["theta12"]
        .as_array()
        .unwrap()
        .iter()
        .zip(results["theta12"][k].as_array().unwrap())
    {
        let (a, b) = (a.as_f64().unwrap(), b.as_f64().unwrap());
        assert!(
            (a - b).abs() <= 1e-4 * b.abs() + 1e-12,
            "run {k}: {a} vs {b}"
        );
    }
}

#[test]
fn experiment_report_is_self_contained_and_animates_runs_with_the_filter_s_cloud() {
    let dir = experiment();
    let html = fs::read_to_string(dir.join("report.html")).unwrap();
    assert!(html.starts_with("<!DOCTYPE html>"));
    // The page states its size, in kB to three digits.
    let at = html.find("This page: ").expect("the page's size") + "This page: ".len();
    let stated: f64 = html[at..].split(" kB").next().unwrap().parse().unwrap();
    let kb = html.len() as f64 / 1e3;
    assert!(
        (stated - kb).abs() <= 0.01 * kb,
        "{stated} kB stated, {kb} kB"
    );
    assert_eq!(external_references(&html), Vec::<String>::new());
    // One inline script besides the data; no script is fetched.
    assert_eq!(html.matches("<script").count(), 2);
    assert!(!html.contains("<script src"));
    // The table: every method beside the paper's figures, as the command prints it.
    let results: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(dir.join("results.json")).unwrap()).unwrap();
    assert_eq!(results["sets"], serde_json::json!([]));
    assert_eq!(results["pf_model"], "coarse");
    for m in results["methods"].as_array().unwrap() {
        let name = m["name"].as_str().unwrap();
        assert!(html.contains(&format!("<td>{name}</td>")), "{name}");
    }
    assert!(html.contains("paper (seed)") && html.contains("<td>2.00</td>"));
    // Figures inline, one per figure of the folder.
    for fig in [
        "templates",
        "responsibilities",
        "estimated-d",
        "estimated-v",
        "pf_calibration",
    ] {
        assert!(html.contains(&format!("id=\"figure-{fig}\"")), "{fig}");
    }
    // The runs: four evaluated ones by default, each with its frames and the filter's cloud,
    // whose final estimate is the one the experiment scored.
    let data = page_data(&html);
    let runs = data["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 4);
    let evaluated: Vec<usize> = results["is_template"]
        .as_array()
        .unwrap()
        .iter()
        .enumerate()
        .filter(|(_, t)| !t.as_bool().unwrap())
        .map(|(k, _)| k)
        .collect();
    let pf = results["methods"]
        .as_array()
        .unwrap()
        .iter()
        .find(|m| m["name"] == "pf")
        .expect("the filter was scored");
    for run in runs {
        let k = run["index"].as_u64().unwrap() as usize;
        let frames = run["frames"].as_array().unwrap().len();
        assert_eq!(
            frames, 76,
            "151 samples at most 150 frames: every other one"
        );
        assert_eq!(run["nodes"].as_array().unwrap().len(), frames);
        assert_eq!(run["nodes"][0].as_array().unwrap().len(), 2 * 21);
        assert_eq!(run["poses"].as_array().unwrap().len(), frames);
        assert_eq!(run["t"].as_array().unwrap().len(), 151);
        // The recording is the experiment's (theta12, to the digits the page keeps).
        assert_recording_is_the_experiment_s(run, &results, k);
        let cloud = &run["pf"];
        assert_eq!(cloud["points"].as_array().unwrap().len(), frames);
        let j = evaluated
            .iter()
            .position(|&e| e == k)
            .expect("an evaluated run");
        let scored = &pf["predictions"][j]["estimate"];
        for u in 0..2 {
            assert_eq!(cloud["last"][u], scored[u]["mean"], "run {k}, unknown {u}");
        }
    }
}

#[test]
fn report_picks_the_runs_asked_for_and_refuses_unknown_ones_leaving_nothing_behind() {
    let source = experiment();
    let dir = temp("picked");
    for f in ["results.json", "templates.svg", "templates.png"] {
        fs::copy(source.join(f), dir.join(f)).unwrap();
    }
    let text = ok(&vibrissa()
        .arg("report")
        .arg(&dir)
        .args(["--runs", "3,0"])
        .output()
        .unwrap());
    assert!(
        text.contains("report.html") && text.contains("2 runs animated"),
        "{text}"
    );
    let html = fs::read_to_string(dir.join("report.html")).unwrap();
    let data = page_data(&html);
    let picked: Vec<u64> = data["runs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["index"].as_u64().unwrap())
        .collect();
    assert_eq!(picked, [0, 3]);
    // A template (run 0) has no estimates; the filter still runs on it.
    assert_eq!(data["runs"][0]["template"], true);
    assert!(data["runs"][0]["pf"].is_object());
    // An unknown run: a clear error, and the page written before is left as it was.
    let before = fs::read(dir.join("report.html")).unwrap();
    let e = failed(
        &vibrissa()
            .arg("report")
            .arg(&dir)
            .args(["--runs", "2,80"])
            .output()
            .unwrap(),
    );
    assert!(
        e.contains("--runs") && e.contains("no run 80") && e.contains("0 to 79"),
        "{e}"
    );
    assert_eq!(fs::read(dir.join("report.html")).unwrap(), before);
    assert_eq!(
        listing(&dir),
        [
            "report.html",
            "results.json",
            "templates.png",
            "templates.svg"
        ]
    );
}

#[test]
fn report_refuses_folders_that_are_not_an_experiment_s() {
    let missing = std::env::temp_dir().join(format!("vibrissa-report-{}-none", std::process::id()));
    let e = failed(&vibrissa().arg("report").arg(&missing).output().unwrap());
    assert!(e.contains("DIR") && e.contains("no such folder"), "{e}");

    let empty = temp("empty");
    let e = failed(&vibrissa().arg("report").arg(&empty).output().unwrap());
    assert!(
        e.contains("not an experiment's output folder") && e.contains("results.json"),
        "{e}"
    );
    assert!(listing(&empty).is_empty());

    let broken = temp("broken");
    fs::write(
        broken.join("results.json"),
        r#"{"family": "e2", "variant": "clean"}"#,
    )
    .unwrap();
    let e = failed(&vibrissa().arg("report").arg(&broken).output().unwrap());
    assert!(
        e.contains("not the results of `vibrissa experiment`") && e.contains("missing field"),
        "{e}"
    );
    assert_eq!(listing(&broken), ["results.json"]);

    fs::write(broken.join("results.json"), "{ not json").unwrap();
    let e = failed(&vibrissa().arg("report").arg(&broken).output().unwrap());
    assert!(e.contains("not valid JSON"), "{e}");

    let delayed = temp("delayed");
    fs::write(
        delayed.join("results.json"),
        r#"{"family": "e2", "max_delay": 0.02, "runs": []}"#,
    )
    .unwrap();
    let e = failed(&vibrissa().arg("report").arg(&delayed).output().unwrap());
    assert!(e.contains("--max-delay"), "{e}");
    assert_eq!(listing(&delayed), ["results.json"]);

    // --report with --max-delay is a usage error before anything runs.
    let out = vibrissa()
        .args([
            "experiment",
            "e2",
            "--max-delay",
            "0.02",
            "--report",
            "--out",
        ])
        .arg(&delayed)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert_eq!(listing(&delayed), ["results.json"]);
}

#[test]
fn simulate_animates_the_run_into_a_gif() {
    let dir = temp("gif");
    let gif = dir.join("run.gif");
    let text = ok(&vibrissa()
        .args([
            "simulate", "e2", "--set", "d=0.02", "--set", "v=0.6", "--out",
        ])
        .arg(dir.join("run.csv"))
        .arg("--animate")
        .arg(&gif)
        .output()
        .unwrap());
    assert!(text.contains("run.gif"), "{text}");
    let mut options = gif::DecodeOptions::new();
    options.set_color_output(gif::ColorOutput::Indexed);
    let mut decoder = options.read_info(fs::File::open(&gif).unwrap()).unwrap();
    assert_eq!((decoder.width(), decoder.height()), (600, 300));
    let mut frames = 0;
    let mut changed_pixels = 0;
    while let Some(frame) = decoder.read_next_frame().unwrap() {
        assert!(frame.left + frame.width <= 600 && frame.top + frame.height <= 300);
        assert_eq!(frame.delay, 4, "25 frames per second");
        if frames > 0 {
            changed_pixels += frame.width as usize * frame.height as usize;
        }
        frames += 1;
    }
    // 151 samples (150 ms at 1 kHz), at most 150 frames: every other sample.
    assert_eq!(frames, 76);
    assert!(changed_pixels > 0, "the picture moves");
    assert!(fs::metadata(&gif).unwrap().len() < 1_000_000);
}

#[test]
fn simulate_refuses_bad_animation_paths_before_writing_anything() {
    let dir = temp("bad-gif");
    let e = failed(
        &vibrissa()
            .args(["simulate", "e2", "--out"])
            .arg(dir.join("run.csv"))
            .arg("--animate")
            .arg(dir.join("run.png"))
            .output()
            .unwrap(),
    );
    assert!(e.contains("run.png") && e.contains(".gif"), "{e}");
    let e = failed(
        &vibrissa()
            .args(["simulate", "e2", "--out"])
            .arg(dir.join("run.csv"))
            .arg("--animate")
            .arg(dir.join("missing/run.gif"))
            .output()
            .unwrap(),
    );
    assert!(
        e.contains("--animate") && e.contains("does not exist"),
        "{e}"
    );
    assert!(listing(&dir).is_empty());
}

#[test]
fn report_re_simulates_a_scenario_family_with_its_overrides_from_anywhere() {
    let dir = temp("family");
    fs::write(
        dir.join("soft_e1.toml"),
        "experiment = \"e1\"\n[whisker]\nyoungs_modulus = 2.6e9\n[unknowns]\nd = [0.016, 0.028]\n[grid]\nd = [0.017, 0.021, 0.025]\n",
    )
    .unwrap();
    // The experiment names its scenario relative to its own folder, with an override.
    ok(&vibrissa()
        .current_dir(&dir)
        .args([
            "experiment",
            "--scenario",
            "soft_e1.toml",
            "--set",
            "whisker.density=1300",
        ])
        .args(["--particles", "16", "--out", "out"])
        .output()
        .unwrap());
    let results: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(dir.join("out/results.json")).unwrap()).unwrap();
    assert_eq!(results["sets"], serde_json::json!(["whisker.density=1300"]));
    assert!(Path::new(results["scenario_file"].as_str().unwrap()).is_absolute());
    // The report, made from elsewhere, re-simulates the very recordings.
    ok(&vibrissa()
        .current_dir(std::env::temp_dir())
        .arg("report")
        .arg(dir.join("out"))
        .arg("--all-runs")
        .output()
        .unwrap());
    let data = page_data(&fs::read_to_string(dir.join("out/report.html")).unwrap());
    let runs = data["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 3);
    for run in runs {
        let k = run["index"].as_u64().unwrap() as usize;
        assert_recording_is_the_experiment_s(run, &results, k);
        // One unknown: the cloud is over d alone.
        assert_eq!(run["pf"]["unknowns"], serde_json::json!(["d"]));
    }
}
