//! Folders of labelled recordings: what is read, and every refusal naming its file and field.

use std::fs;
use std::path::{Path, PathBuf};
use vibrissa_io::labelled::{read_labelled, Labelled, Options};
use vibrissa_io::scenario::Document;

/// A fresh folder for this test's files.
fn temp_dir(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("labelled-{name}"));
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).unwrap();
    dir
}

/// A recording of `n` rows at `rate` Hz from `t0`, with the contract's observed channels.
fn recording(n: usize, rate: f64, t0: f64) -> String {
    let mut text = String::from("# vibrissa = 0.1.0\nt,theta01,theta12,m0,fx,fy\n");
    for k in 0..n {
        let t = t0 + k as f64 / rate;
        text.push_str(&format!(
            "{t},{},{},0,0,0\n",
            0.01 * k as f64,
            0.002 * k as f64
        ));
    }
    text
}

/// A valid folder: two recordings of different lengths, a sidecar and a README.
fn good_folder(name: &str) -> PathBuf {
    let dir = temp_dir(name);
    fs::write(dir.join("a.csv"), recording(20, 1000.0, 0.0)).unwrap();
    fs::write(dir.join("b.csv"), recording(31, 1000.0, 0.5)).unwrap();
    fs::write(dir.join("a.json"), "{\"segments\": 50}").unwrap();
    fs::write(dir.join("README.md"), "notes").unwrap();
    fs::write(
        dir.join("truth.csv"),
        "# labels of the strikes\nfile,d,v\na.csv,0.015,0.3\nb.csv,0.030,1.5\n",
    )
    .unwrap();
    dir
}

fn nominal() -> Document {
    Document::load("e2", &[]).unwrap()
}

fn read(dir: &Path) -> Result<Labelled, String> {
    read_labelled(dir, &nominal(), &Options::default()).map_err(|e| e.to_string())
}

fn refused(dir: &Path) -> String {
    match read(dir) {
        Ok(l) => panic!("expected a refusal, read {} recordings", l.recordings.len()),
        Err(e) => e,
    }
}

#[test]
fn a_good_folder_is_read_with_its_labels_and_rate() {
    let dir = good_folder("good");
    let set = read(&dir).unwrap();
    assert_eq!(set.keys, ["d", "v"]);
    assert_eq!(set.recordings.len(), 2);
    let a = &set.recordings[0];
    assert_eq!(a.file, "a.csv");
    assert_eq!(a.labels, [("d".to_string(), 0.015), ("v".to_string(), 0.3)]);
    assert_eq!(a.overrides(), ["d=0.015", "v=0.3"]);
    assert!((a.step - 1e-3).abs() < 1e-12);
    assert_eq!(a.t().len(), 20);
    assert_eq!(set.recordings[1].t().len(), 31);
    assert_eq!(set.recordings[1].t()[0], 0.5);
    assert!(set.recordings[1].channel("m0").is_some());
    assert!(set.ignored.is_empty());
}

#[test]
fn a_missing_recording_names_truth_line_and_file() {
    let dir = good_folder("missing");
    fs::remove_file(dir.join("b.csv")).unwrap();
    let e = refused(&dir);
    assert!(
        e.contains("truth.csv, line 4") && e.contains("`b.csv`") && e.contains("does not exist"),
        "{e}"
    );
}

#[test]
fn an_unlisted_recording_is_refused_unless_ignored() {
    let dir = good_folder("unlisted");
    fs::write(dir.join("c.CSV"), recording(20, 1000.0, 0.0)).unwrap();
    let e = refused(&dir);
    assert!(
        e.contains("c.CSV") && e.contains("not named in truth.csv"),
        "{e}"
    );
    let set = read_labelled(
        &dir,
        &nominal(),
        &Options {
            ignore_unlisted: true,
        },
    )
    .unwrap();
    assert_eq!(set.ignored, ["c.CSV"]);
    assert_eq!(set.recordings.len(), 2);
}

#[test]
fn a_key_of_whole_numbers_can_be_a_label() {
    // `segments` takes whole numbers: its labels are written as integers, and a real-valued
    // key's whole-numbered label (v = 1) reads back as the same real.
    let dir = good_folder("wholekey");
    fs::write(
        dir.join("truth.csv"),
        "file,d,v,segments\na.csv,0.015,1,12\nb.csv,0.03,1.5,16\n",
    )
    .unwrap();
    let set = read(&dir).unwrap();
    assert_eq!(set.keys, ["d", "v", "segments"]);
    assert_eq!(
        set.recordings[0].overrides(),
        ["d=0.015", "v=1", "segments=12"]
    );
    assert_eq!(
        set.recordings[1].overrides(),
        ["d=0.03", "v=1.5", "segments=16"]
    );
    let loaded = nominal()
        .loaded_with(&set.recordings[0].overrides())
        .unwrap();
    assert_eq!(loaded.scenario.segments, 12);
    // A fraction there is named as the value it is, with its line, not as an unknown key.
    fs::write(
        dir.join("truth.csv"),
        "file,d,v,segments\na.csv,0.015,1,12.5\nb.csv,0.03,1.5,16\n",
    )
    .unwrap();
    let e = refused(&dir);
    assert!(
        e.contains("`segments` line 2: 12.5 is not a value the key takes") && !e.contains("no key"),
        "{e}"
    );
}

#[test]
fn a_label_the_scenario_does_not_take_is_named() {
    let dir = good_folder("badkey");
    fs::write(
        dir.join("truth.csv"),
        "file,d,whisker.lenght\na.csv,0.015,0.03\nb.csv,0.03,0.03\n",
    )
    .unwrap();
    let e = refused(&dir);
    assert!(
        e.contains("truth.csv") && e.contains("`whisker.lenght`") && e.contains("no key"),
        "{e}"
    );
    // A key of the schema that the scenario refuses for this value is named with its row.
    fs::write(
        dir.join("truth.csv"),
        "file,d,whisker.length\na.csv,0.015,0.03\nb.csv,0.03,-1\n",
    )
    .unwrap();
    let e = refused(&dir);
    assert!(
        e.contains("truth.csv, line 3") && e.contains("whisker.length"),
        "{e}"
    );
}

#[test]
fn non_finite_or_missing_labels_are_named() {
    let dir = good_folder("nonfinite");
    for (bad, what) in [
        ("nan", "not finite"),
        ("inf", "not finite"),
        ("fast", "not a number"),
    ] {
        fs::write(
            dir.join("truth.csv"),
            format!("file,d,v\na.csv,0.015,0.3\nb.csv,0.03,{bad}\n"),
        )
        .unwrap();
        let e = refused(&dir);
        assert!(
            e.contains("truth.csv, line 3") && e.contains("column `v`") && e.contains(what),
            "{e}"
        );
    }
    fs::write(dir.join("truth.csv"), "name,d\na.csv,0.015\n").unwrap();
    assert!(refused(&dir).contains("no `file` column"));
    fs::write(dir.join("truth.csv"), "file,d\na.csv,0.015\na.csv,0.02\n").unwrap();
    assert!(refused(&dir).contains("named twice"));
    fs::remove_file(dir.join("truth.csv")).unwrap();
    assert!(refused(&dir).contains("no truth.csv"));
}

#[test]
fn a_recording_at_another_rate_is_named() {
    let dir = good_folder("rate");
    fs::write(dir.join("c.csv"), recording(40, 2000.0, 0.0)).unwrap();
    fs::write(
        dir.join("truth.csv"),
        "file,d,v\na.csv,0.015,0.3\nb.csv,0.03,1.5\nc.csv,0.02,0.6\n",
    )
    .unwrap();
    let e = refused(&dir);
    assert!(
        e.contains("c.csv") && e.contains("2000.000000 Hz") && e.contains("1000.000000 Hz"),
        "{e}"
    );
}

#[test]
fn times_that_do_not_increase_or_jump_are_named_by_row() {
    let dir = good_folder("times");
    // Row 6 repeats row 5's time (line 7 of the file: a comment and the header come first).
    let mut text = recording(20, 1000.0, 0.0);
    text = text.replace("\n0.005,", "\n0.004,");
    fs::write(dir.join("a.csv"), &text).unwrap();
    let e = refused(&dir);
    assert!(
        e.contains("a.csv, line 8") && e.contains("row 6") && e.contains("does not increase"),
        "{e}"
    );
    // A 2% longer step at row 11.
    let text = recording(20, 1000.0, 0.0).replace("\n0.01,", "\n0.01002,");
    fs::write(dir.join("a.csv"), &text).unwrap();
    let e = refused(&dir);
    assert!(
        e.contains("a.csv, line 13") && e.contains("row 11") && e.contains("1%"),
        "{e}"
    );
    // Jitter within 1% is accepted.
    let text = recording(20, 1000.0, 0.0).replace("\n0.01,", "\n0.010005,");
    fs::write(dir.join("a.csv"), &text).unwrap();
    read(&dir).unwrap();
}

#[test]
fn missing_required_columns_are_named() {
    let dir = good_folder("columns");
    fs::write(dir.join("b.csv"), "t,theta01,m0\n0,0,0\n0.001,0,0\n").unwrap();
    let e = refused(&dir);
    assert!(
        e.contains("b.csv") && e.contains("missing column theta12"),
        "{e}"
    );
    // Only t, theta01 and theta12 are required.
    fs::write(dir.join("b.csv"), "t,theta12,theta01\n0,0,0\n0.001,0,0\n").unwrap();
    read(&dir).unwrap();
}
