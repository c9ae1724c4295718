//! The `[sensors]` and `[calibration]` tables, and scenario documents written back as files.

use std::fs;
use std::path::PathBuf;
use vibrissa_core::sim::{self, Response};
use vibrissa_io::scenario::{load_full, CalibratedParameter, Calibration, ChannelValues, Document};
use vibrissa_io::{load, load_str};

fn temp_dir(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("sensors-{name}"));
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).unwrap();
    dir
}

fn err(text: &str) -> String {
    match load_str(text, "s.toml", &[]) {
        Ok(s) => panic!("expected an error, loaded {s:?}"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn sensors_table_sets_gains_and_offsets_with_defaults() {
    let s = load_str(
        "[sensors]\ntheta01 = { gain = 1.02, offset = 0.003 }\nfx = { offset = -1e-5 }\nm0 = { gain = -0.5 }\n",
        "s.toml",
        &[],
    )
    .unwrap();
    let r = s.sensor_response;
    assert_eq!(
        r.theta01,
        Response {
            gain: 1.02,
            offset: 0.003
        }
    );
    assert_eq!(r.theta12, Response::default());
    assert_eq!(
        r.fx,
        Response {
            gain: 1.0,
            offset: -1e-5
        }
    );
    assert_eq!(r.m0.gain, -0.5);
    // Without the table: the identity, as before.
    assert!(load("e2", &[])
        .unwrap()
        .sensor_response
        .to_array()
        .iter()
        .all(Response::is_identity));
    // Overrides reach it too.
    let s = load("e2", &["sensors.fy.gain=1.5".to_string()]).unwrap();
    assert_eq!(s.sensor_response.fy.gain, 1.5);
}

#[test]
fn bad_sensor_entries_name_the_field() {
    let e = err("[sensors]\ntheta12 = { gain = 0.0 }\n");
    assert!(
        e.contains("sensors.theta12.gain") && e.contains("other than 0"),
        "{e}"
    );
    let e = err("[sensors]\nm0 = { gain = nan }\n");
    assert!(e.contains("sensors.m0.gain"), "{e}");
    let e = err("[sensors]\nfx = { offset = inf }\n");
    assert!(e.contains("sensors.fx.offset"), "{e}");
    let e = err("[sensors]\nfz = { gain = 1.0 }\n");
    assert!(e.contains("fz") && e.contains("theta01"), "{e}");
    let e = err("[sensors]\nfx = { gain = 1.0, scale = 2 }\n");
    assert!(e.contains("scale") && e.contains("offset"), "{e}");
}

#[test]
fn gains_and_offsets_scale_and_shift_the_recorded_channels() {
    let plain = load("e2", &["d=0.02".to_string()]).unwrap();
    let mut scaled = plain.clone();
    let gains = [1.1, 0.9, -2.0, 1.5, 0.7];
    let offsets = [0.01, -0.02, 1e-6, 2e-5, 0.0];
    scaled.sensor_response = sim::SensorResponse::from_array(std::array::from_fn(|c| Response {
        gain: gains[c],
        offset: offsets[c],
    }));
    let a = sim::run(&plain, &mut |_| {}).unwrap();
    let b = sim::run(&scaled, &mut |_| {}).unwrap();
    for (ra, rb) in a.rows.iter().zip(&b.rows) {
        for c in 0..5 {
            let want = gains[c] * ra[c + 1] + offsets[c];
            assert!((rb[c + 1] - want).abs() <= 1e-12 * want.abs().max(1e-9));
        }
        // Time, contact and the contact point are not sensor channels.
        assert_eq!(ra[0], rb[0]);
        assert_eq!(ra[6], rb[6]);
    }
}

#[test]
fn identity_response_keeps_every_bit() {
    let r = Response::default();
    for x in [0.0, -0.0, 1.5e-300, -3.25, f64::NAN] {
        assert_eq!(r.apply(x).to_bits(), x.to_bits());
    }
}

fn sample_calibration() -> Calibration {
    Calibration {
        labelled: Some("calib".into()),
        recordings: Some(9),
        rms_before: ChannelValues::from_array([Some(0.01), Some(0.02), Some(3e-6), None, None]),
        rms_after: ChannelValues::from_array([Some(0.001), Some(0.002), Some(3e-7), None, None]),
        noise: ChannelValues::default(),
        parameters: vec![
            CalibratedParameter {
                key: "whisker.youngs_modulus".into(),
                nominal: Some(3.3e9),
                value: 3.1e9,
                std_error: Some(2e7),
                determined: true,
                note: None,
            },
            CalibratedParameter {
                key: "whisker.follicle.stiffness".into(),
                nominal: None,
                value: 0.0,
                std_error: None,
                determined: false,
                note: Some("stiffer than the recordings resolve: kept clamped".into()),
            },
        ],
        correlation: None,
    }
}

#[test]
fn calibration_table_is_accepted_and_read_back() {
    let text = r#"
experiment = "e2"
[calibration]
labelled = "calib"
recordings = 9
rms_before = { theta01 = 0.01, theta12 = 0.02, m0 = 3e-6 }
rms_after = { theta01 = 0.001, theta12 = 0.002, m0 = 3e-7 }
[[calibration.parameters]]
key = "whisker.youngs_modulus"
nominal = 3.3e9
value = 3.1e9
std_error = 2e7
determined = true
[[calibration.parameters]]
key = "whisker.follicle.stiffness"
value = 0.0
determined = false
note = "stiffer than the recordings resolve: kept clamped"
"#;
    let dir = temp_dir("calibration");
    let path = dir.join("fitted.toml");
    fs::write(&path, text).unwrap();
    let loaded = load_full(path.to_str().unwrap(), &[]).unwrap();
    assert_eq!(loaded.calibration, Some(sample_calibration()));
    // The record changes nothing in the run.
    assert_eq!(loaded.scenario, load("e2", &[]).unwrap());

    // Unknown keys and bad numbers are refused by name.
    let e = err("[calibration]\nrms_after = { theta3 = 1.0 }\n");
    assert!(e.contains("theta3"), "{e}");
    let e = err("[calibration]\nsurprise = 1\n");
    assert!(e.contains("surprise"), "{e}");
    let e = err("[[calibration.parameters]]\nkey = \"x\"\nvalue = 1.0\ndetermined = true\nstd_error = -1.0\n");
    assert!(e.contains("calibration.parameters[0].std_error"), "{e}");
    let e = err("[[calibration.parameters]]\nkey = \"x\"\ndetermined = true\n");
    assert!(e.contains("value"), "{e}");
}

#[test]
fn a_correlation_of_the_determined_parameters_is_read_back_and_checked() {
    let head = r#"
experiment = "e2"
[[calibration.parameters]]
key = "whisker.youngs_modulus"
value = 3.1e9
std_error = 2e7
determined = true
[[calibration.parameters]]
key = "whisker.density"
value = 1000.0
std_error = 30.0
determined = true
[[calibration.parameters]]
key = "sensors.m0.gain"
value = 1.0
determined = false
"#;
    let with = |table: &str| format!("{head}[calibration.correlation]\n{table}");
    let good = with("keys = [\"whisker.youngs_modulus\", \"whisker.density\"]\nmatrix = [[1.0, 0.9], [0.9, 1.0]]\n");
    let dir = temp_dir("correlation");
    let path = dir.join("fitted.toml");
    fs::write(&path, &good).unwrap();
    let loaded = load_full(path.to_str().unwrap(), &[]).unwrap();
    let record = loaded.calibration.unwrap();
    let c = record.correlation.clone().unwrap();
    assert_eq!(
        c.get("whisker.density", "whisker.youngs_modulus"),
        Some(0.9)
    );
    assert_eq!(c.get("whisker.density", "sensors.m0.gain"), None);
    assert_eq!(
        c.strongest(0.5, |_| true),
        [("whisker.youngs_modulus", "whisker.density", 0.9)]
    );
    assert!(c.strongest(0.95, |_| true).is_empty());
    assert!(c.strongest(0.5, |k| k != "whisker.density").is_empty());
    // Written back by a document, it reads the same.
    let mut doc = Document::load(path.to_str().unwrap(), &[]).unwrap();
    doc.set_calibration(&record).unwrap();
    let out = dir.join("out.toml");
    doc.write(&out).unwrap();
    let again = load_full(out.to_str().unwrap(), &[]).unwrap();
    assert_eq!(again.calibration.unwrap(), record);

    for (table, field, what) in [
        (
            "keys = [\"whisker.youngs_modulus\", \"sensors.m0.gain\"]\nmatrix = [[1.0, 0.0], [0.0, 1.0]]\n",
            "correlation.keys[1]",
            "determined",
        ),
        (
            "keys = [\"whisker.density\", \"whisker.density\"]\nmatrix = [[1.0, 0.0], [0.0, 1.0]]\n",
            "correlation.keys[1]",
            "once",
        ),
        (
            "keys = [\"whisker.youngs_modulus\", \"whisker.density\"]\nmatrix = [[1.0, 0.9]]\n",
            "correlation.matrix",
            "one row per key",
        ),
        (
            "keys = [\"whisker.youngs_modulus\", \"whisker.density\"]\nmatrix = [[1.0, 0.9], [0.9]]\n",
            "correlation.matrix[1]",
            "one entry per key",
        ),
        (
            "keys = [\"whisker.youngs_modulus\", \"whisker.density\"]\nmatrix = [[1.0, 0.9], [0.8, 1.0]]\n",
            "correlation.matrix[0][1]",
            "symmetric",
        ),
        (
            "keys = [\"whisker.youngs_modulus\", \"whisker.density\"]\nmatrix = [[1.0, 1.5], [1.5, 1.0]]\n",
            "correlation.matrix[0][1]",
            "[-1, 1]",
        ),
        (
            "keys = [\"whisker.youngs_modulus\", \"whisker.density\"]\nmatrix = [[0.5, 0.0], [0.0, 1.0]]\n",
            "correlation.matrix[0][0]",
            "diagonal",
        ),
    ] {
        fs::write(&path, with(table)).unwrap();
        let e = load_full(path.to_str().unwrap(), &[]).unwrap_err().to_string();
        assert!(e.contains(field) && e.contains(what), "{table}: {e}");
    }
}

#[test]
fn edited_documents_write_files_that_load_the_same() {
    let dir = temp_dir("document");
    // A scenario with a trajectory relative to its own folder, written to another folder.
    let src = dir.join("src");
    fs::create_dir_all(&src).unwrap();
    fs::write(src.join("whisk.csv"), "t,angle\n0,0\n0.1,0.2\n").unwrap();
    fs::write(
        src.join("nominal.toml"),
        "# comment\n[whisker]\nyoungs_modulus = 3e9\n[base]\nkind = \"trajectory\"\nfile = \"whisk.csv\"\n",
    )
    .unwrap();
    let mut doc = Document::load(src.join("nominal.toml").to_str().unwrap(), &[]).unwrap();
    doc.set("whisker.youngs_modulus=2.5e9").unwrap();
    doc.set("sensors.m0.gain=1.05").unwrap();
    doc.set_calibration(&sample_calibration()).unwrap();
    let out = dir.join("out");
    fs::create_dir_all(&out).unwrap();
    let fitted = out.join("fitted.toml");
    doc.write(&fitted).unwrap();

    let loaded = load_full(fitted.to_str().unwrap(), &[]).unwrap();
    let edited = doc.loaded().unwrap();
    assert_eq!(loaded.scenario, edited.scenario);
    assert_eq!(loaded.scenario.whisker.youngs_modulus, 2.5e9);
    assert_eq!(loaded.scenario.sensor_response.m0.gain, 1.05);
    assert_eq!(loaded.calibration, Some(sample_calibration()));

    // A document that does not load is not written.
    doc.set("whisker.length=-1").unwrap();
    let bad = out.join("bad.toml");
    let e = doc.write(&bad).unwrap_err().to_string();
    assert!(e.contains("whisker.length"), "{e}");
    assert!(!bad.exists());
    assert_eq!(fs::read_dir(&out).unwrap().count(), 1);

    // Extra overrides on a copy leave the document alone.
    let d = Document::load("e2", &[]).unwrap();
    let l = d.loaded_with(&["d=0.015".to_string()]).unwrap();
    assert_eq!(l.experiment.unwrap().d, 0.015);
    assert_eq!(d.loaded().unwrap().experiment.unwrap().d, 0.020);
}
