//! One scenario's whisker given to another's array (`estimate --shapes ... --whisker-from`).

use std::fs;
use std::path::PathBuf;
use vibrissa_core::chain::Discretisation;
use vibrissa_core::whisker::Follicle;
use vibrissa_io::scenario::{open_adopting, WhiskerSource, WhiskerSources};

/// A fresh folder for this test's files.
fn temp_dir(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("adopt-{name}"));
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).unwrap();
    dir
}

/// A whisker as calibration writes one: the chain, a fitted whisker, the sensors.
const FITTED: &str = r#"
experiment = "e2"
segments = 12
discretisation = "seed"

[whisker]
preset = "w30"
youngs_modulus = 2.4e9
density = 850.0
follicle = { kind = "spring", stiffness = 2.5e-4, damping = 1e-7 }

[sensors]
theta12 = { gain = 0.38, offset = -0.0009 }
fy = { gain = 1.06 }
"#;

/// An array of two whiskers past a peg, with a whisker, chain and sensors of its own.
const ARRAY: &str = r#"
duration = 0.05
segments = 30
sample_rate = 1000

[whisker]
preset = "w30"
tip_radius = 5e-5

[sensors]
m0 = { gain = 2.0 }

[[whiskers]]
name = "a"
position = [0.0, 0.0]

[[whiskers]]
name = "b"
position = [0.0, 0.002]

[[objects]]
shape = "circle"
radius = 0.004
position = [0.02, -0.02]
velocity = [0.0, 0.5]

[unknowns]
"objects.0.position.0" = { range = [0.015, 0.025], name = "x" }
"#;

/// [`ARRAY`] with `line` added to its whisker `b`'s entry.
fn with_b(line: &str) -> String {
    ARRAY.replace(
        "position = [0.0, 0.002]",
        &format!("position = [0.0, 0.002]\n{line}"),
    )
}

#[test]
fn every_whisker_of_an_array_gets_the_whisker_chain_and_sensors_and_nothing_else() {
    let dir = temp_dir("whole");
    let fitted = dir.join("fitted.toml");
    fs::write(&fitted, FITTED).unwrap();
    let source: WhiskerSources = WhiskerSource::read(fitted.to_str().unwrap())
        .unwrap()
        .into();
    assert!(!source.is_calibrated());
    let origin = dir.join("array.toml");
    let (_, loaded) =
        open_adopting(origin.to_str().unwrap(), Some(ARRAY), &[], Some(&source)).unwrap();
    let s = &loaded.scenario;
    // The source's chain and whisker; a key it leaves out (tip_radius) takes the preset's,
    // not the array file's.
    assert_eq!((s.segments, s.discretisation), (12, Discretisation::Seed));
    assert_eq!(s.whisker.youngs_modulus, 2.4e9);
    assert_eq!(s.whisker.density, 850.0);
    assert_eq!(s.whisker.tip_radius, s.whisker.base_radius);
    assert!(matches!(s.whisker.follicle, Follicle::Spring { .. }));
    // The source's sensors replace the file's: m0's gain of 2 is gone.
    let r = &s.sensor_response;
    assert_eq!(r.theta12.gain, 0.38);
    assert_eq!(r.theta12.offset, -0.0009);
    assert_eq!(r.fy.gain, 1.06);
    assert_eq!(r.m0.gain, 1.0);
    // The array's own: its whiskers (sharing the scenario's whisker), objects, timing.
    assert_eq!(loaded.whiskers.len(), 2);
    assert!(loaded.whiskers.iter().all(|m| m.whisker.is_none()));
    assert_eq!(s.duration, 0.05);
    assert_eq!(s.objects.len(), 1);
    assert!(loaded.family.is_some());
    // A source that does not name contact_substeps leaves the array's own.
    assert_eq!(s.integrator.contact_substeps, 1);
    // Overrides apply after the whisker is given.
    let (_, edited) = open_adopting(
        origin.to_str().unwrap(),
        Some(ARRAY),
        &["whisker.density=900".to_string()],
        Some(&source),
    )
    .unwrap();
    assert_eq!(edited.scenario.whisker.density, 900.0);
    assert_eq!(edited.scenario.whisker.youngs_modulus, 2.4e9);
}

#[test]
fn an_array_is_no_source_and_whiskers_of_their_own_cannot_be_replaced() {
    let dir = temp_dir("refused");
    let array = dir.join("array.toml");
    fs::write(&array, ARRAY).unwrap();
    let err = WhiskerSource::read(array.to_str().unwrap())
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("`whiskers`") && err.contains("one whisker"),
        "{err}"
    );

    let fitted = dir.join("fitted.toml");
    fs::write(&fitted, FITTED).unwrap();
    let source: WhiskerSources = WhiskerSource::read(fitted.to_str().unwrap())
        .unwrap()
        .into();
    let own = with_b("whisker = { length = 0.025 }");
    let err = open_adopting("own.toml", Some(&own), &[], Some(&source))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("whiskers.b.whisker") && err.contains("length") && err.contains("alike"),
        "{err}"
    );
    // Nor its own sensors, which would read it otherwise than the file's.
    let own = with_b("sensors = { m0 = { gain = 1.1 } }");
    let err = open_adopting("own.toml", Some(&own), &[], Some(&source))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("whiskers.b.sensors") && err.contains("b=FILE"),
        "{err}"
    );

    // A malformed source is refused as any scenario is, naming its key.
    let bad = dir.join("bad.toml");
    fs::write(&bad, "[whisker]\nyoungs_modulus = -3e9\n").unwrap();
    let err = WhiskerSource::read(bad.to_str().unwrap())
        .unwrap_err()
        .to_string();
    assert!(err.contains("youngs_modulus"), "{err}");
}

#[test]
fn contact_is_stepped_as_finely_as_the_source_was_fitted() {
    let dir = temp_dir("contact");
    // Calibrated at 0.1 ms with five substeps near contact: contact at 20 µs.
    let fitted = dir.join("fitted.toml");
    fs::write(&fitted, format!("contact_substeps = 5\n{FITTED}")).unwrap();
    let source: WhiskerSources = WhiskerSource::read(fitted.to_str().unwrap())
        .unwrap()
        .into();
    let substeps = |array: &str| {
        let (_, loaded) = open_adopting("array.toml", Some(array), &[], Some(&source)).unwrap();
        (
            loaded.scenario.integrator.dt,
            loaded.scenario.integrator.contact_substeps,
        )
    };
    // At the array's own step: 0.1 ms in five, 50 µs in three (ceil 2.5), 10 µs needs none.
    assert_eq!(substeps(ARRAY), (1e-4, 5));
    assert_eq!(substeps(&format!("dt = 5e-5\n{ARRAY}")), (5e-5, 3));
    assert_eq!(substeps(&format!("dt = 1e-5\n{ARRAY}")), (1e-5, 1));
    // An array that already steps contact more finely keeps its own count.
    assert_eq!(
        substeps(&format!("contact_substeps = 8\n{ARRAY}")),
        (1e-4, 8)
    );
}

/// A second fitted whisker on the same chain, as calibration of another whisker of the array
/// on its own strikes writes it.
const FITTED_B: &str = r#"
experiment = "e2"
segments = 12
discretisation = "seed"
contact_substeps = 5

[whisker]
youngs_modulus = 3.1e9
tip_radius = 4e-5

[sensors]
theta01 = { gain = 0.9 }
"#;

#[test]
fn a_named_whisker_of_the_array_gets_its_own_whisker_and_sensors() {
    let dir = temp_dir("own");
    let (fitted, fitted_b) = (dir.join("fitted.toml"), dir.join("b.toml"));
    fs::write(&fitted, FITTED).unwrap();
    fs::write(&fitted_b, FITTED_B).unwrap();
    let spec = |s: &str| s.to_string();
    let (a_file, b_file) = (fitted.display().to_string(), fitted_b.display().to_string());
    let sources = WhiskerSources::read(&[spec(&a_file), format!("b={b_file}")]).unwrap();
    assert_eq!(sources.own.len(), 1);
    assert!(sources.describe().contains("b: "), "{}", sources.describe());
    let (_, loaded) = open_adopting("array.toml", Some(ARRAY), &[], Some(&sources)).unwrap();
    let s = &loaded.scenario;
    // `a` shares the scenario's whisker and sensors: those of the file given to every whisker.
    assert_eq!(loaded.whiskers[0].name, "a");
    assert!(loaded.whiskers[0].whisker.is_none() && loaded.whiskers[0].sensors.is_none());
    assert_eq!(s.whisker.youngs_modulus, 2.4e9);
    assert_eq!(s.sensor_response.theta12.gain, 0.38);
    // `b` has its file's: its fields over the default preset (not over the scenario's whisker),
    // and its sensors whole (theta12's gain is 1, not the other file's 0.38).
    let b = &loaded.whiskers[1];
    let w = b.whisker.as_ref().unwrap();
    assert_eq!((w.youngs_modulus, w.tip_radius), (3.1e9, 4e-5));
    assert_eq!(
        w.density,
        vibrissa_core::whisker::WhiskerParams::w30().density
    );
    assert!(matches!(w.follicle, Follicle::Clamped));
    let r = b.sensors.unwrap();
    assert_eq!((r.theta01.gain, r.theta12.gain, r.fy.gain), (0.9, 1.0, 1.0));
    // One chain for the array, and contact as finely as the finest file asks.
    assert_eq!((s.segments, s.discretisation), (12, Discretisation::Seed));
    assert_eq!(s.integrator.contact_substeps, 5);
    // The mounted scenario of `b` reads it through its own sensors.
    let mb = b.scenario(s, 1);
    assert_eq!(mb.sensor_response.theta01.gain, 0.9);
    assert_eq!(mb.whisker.youngs_modulus, 3.1e9);

    // Named whiskers alone: the first file's chain becomes the array's.
    let only = WhiskerSources::read(&[format!("b={b_file}")]).unwrap();
    let (_, loaded) = open_adopting("array.toml", Some(ARRAY), &[], Some(&only)).unwrap();
    assert_eq!(loaded.scenario.segments, 12);
    assert!(loaded.whiskers[0].whisker.is_none());
    assert_eq!(loaded.scenario.sensor_response.m0.gain, 2.0);
    assert_eq!(loaded.whiskers[1].sensors.unwrap().m0.gain, 1.0);
    // A whisker of its own in the array file is replaced when that whisker is named.
    let own = with_b("whisker = { length = 0.025 }");
    let (_, loaded) = open_adopting("own.toml", Some(&own), &[], Some(&sources)).unwrap();
    assert_eq!(loaded.whiskers[1].whisker.as_ref().unwrap().length, 0.03);
}

#[test]
fn named_whiskers_are_refused_by_name_chain_and_repetition() {
    let dir = temp_dir("own-refused");
    let (fitted, fitted_b) = (dir.join("fitted.toml"), dir.join("b.toml"));
    fs::write(&fitted, FITTED).unwrap();
    fs::write(&fitted_b, FITTED_B).unwrap();
    let (a_file, b_file) = (fitted.display().to_string(), fitted_b.display().to_string());
    let open = |specs: &[String], text: &str| {
        let sources = WhiskerSources::read(specs)?;
        open_adopting("array.toml", Some(text), &[], Some(&sources)).map(|_| ())
    };
    let err = |specs: &[String], text: &str| open(specs, text).unwrap_err().to_string();
    // A name the array does not have: the message lists the names it has.
    let e = err(&[format!("c9={b_file}")], ARRAY);
    assert!(e.contains("`c9`") && e.contains("a, b"), "{e}");
    // A scenario of one whisker has no names.
    let single = "duration = 0.05\n[[objects]]\nshape = \"circle\"\nradius = 0.004\nposition = [0.02, -0.02]\nvelocity = [0.0, 0.5]\n[unknowns]\n\"objects.0.position.0\" = { range = [0.015, 0.025] }\n";
    let e = err(&[format!("b={b_file}")], single);
    assert!(e.contains("no array of whiskers"), "{e}");
    // Files fitted on other chains.
    let other = dir.join("other.toml");
    fs::write(&other, FITTED_B.replace("segments = 12", "segments = 20")).unwrap();
    let e = err(&[a_file.clone(), format!("b={}", other.display())], ARRAY);
    assert!(e.contains("segments") && e.contains("one chain"), "{e}");
    // A name twice, or two files for every whisker.
    let e = err(&[format!("b={b_file}"), format!("b={a_file}")], ARRAY);
    assert!(e.contains("twice"), "{e}");
    let e = err(&[a_file.clone(), b_file.clone()], ARRAY);
    assert!(e.contains("second whisker for every whisker"), "{e}");
    // A missing file is named.
    let e = err(&[format!("b={}", dir.join("none.toml").display())], ARRAY);
    assert!(e.contains("none.toml"), "{e}");
    // The array's own per-whisker sensors are checked like the scenario's.
    let bad = with_b("sensors = { fx = { gain = 0.0 } }");
    let e = err(&[], &bad);
    assert!(e.contains("whiskers[1].sensors.fx.gain"), "{e}");
}
