//! Calibration against recordings whose whisker is known: the fit must find it again.

use std::path::{Path, PathBuf};
use vibrissa_core::sim::{self, COLUMNS};
use vibrissa_infer::calibrate::{calibrate, contact_resolution, Settings};
use vibrissa_io::labelled::{read_labelled, Options};
use vibrissa_io::scenario::Document;
use vibrissa_io::series::{self, Series};

/// Short strikes keep the test quick: the approach, the release and some ringing.
const SHORT: &str = "duration=0.08";

fn folder(name: &str) -> PathBuf {
    let dir =
        std::env::temp_dir().join(format!("vibrissa-calibrate-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Writes strikes of `truth` (e2 with these overrides) at the labels into `dir`, with truth.csv.
/// Contact is stepped and held as calibration steps and holds it (a recording resolves it
/// finely, and a real whisker, or another engine's, stays on a surface it is pressed against).
fn strikes(dir: &Path, truth: &[&str], labels: &[(f64, f64)]) {
    let doc = Document::load(
        "e2",
        &[
            "contact_substeps=5".to_string(),
            "hold_contacts=true".into(),
        ],
    )
    .unwrap();
    let mut listing = String::from("file,d,v\n");
    for (k, (d, v)) in labels.iter().enumerate() {
        let mut sets: Vec<String> = truth.iter().map(|s| s.to_string()).collect();
        sets.push(format!("d={d}"));
        sets.push(format!("v={v}"));
        let scenario = doc.loaded_with(&sets).unwrap().scenario;
        let out = sim::run(&scenario, &mut |_| {}).unwrap();
        let mut series = Series::new(&COLUMNS);
        for row in &out.rows {
            series.push_row(row);
        }
        let name = format!("strike{k}.csv");
        series::write(&series, dir.join(&name)).unwrap();
        listing.push_str(&format!("{name},{d},{v}\n"));
    }
    std::fs::write(dir.join("truth.csv"), listing).unwrap();
}

fn value(fit: &vibrissa_infer::calibrate::Fit, key: &str) -> f64 {
    fit.parameters
        .iter()
        .find(|p| p.key == key)
        .map(|p| p.value)
        .unwrap_or_else(|| panic!("no parameter {key}"))
}

#[test]
fn a_stiffer_lighter_whisker_with_a_sensor_gain_draws_the_fit_towards_it() {
    let dir = folder("found");
    // Modulus +15%, density −10%, θ12's gain +4%: within what the fit is built for.
    let truth = [
        SHORT,
        "whisker.youngs_modulus=3.45e9",
        "whisker.density=990.0",
        "sensors.theta12={ gain = 1.04, offset = 0.002 }",
    ];
    let labels = [(0.016, 0.4), (0.022, 0.9), (0.028, 1.4), (0.019, 1.2)];
    strikes(&dir, &truth, &labels);
    let nominal = Document::load("e2", &[SHORT.to_string()]).unwrap();
    let set = read_labelled(&dir, &nominal, &Options::default()).unwrap();
    let fit = calibrate(&nominal, &set, &Settings::default(), &mut |_| {}).unwrap();

    // The recordings are noise-free: the fitted model must follow them far better than the
    // nominal one, and the material must move towards the truth. (The fit does not reach the
    // truth exactly: with the taper, the follicle, the damping and the time offset free beside
    // the gains it stalls in a shallow valley where θ01's gain trades against the follicle;
    // docs/calibration.md has the figures.)
    for c in &fit.channels {
        assert!(
            c.rms_after < 0.5 * c.rms_before,
            "{}: residual RMS {} after, {} before",
            c.name,
            c.rms_after,
            c.rms_before
        );
    }
    let e = value(&fit, "whisker.youngs_modulus");
    let rho = value(&fit, "whisker.density");
    assert!(
        (e - 3.45e9).abs() < 0.5 * (3.0e9 - 3.45f64 * 1e9).abs(),
        "modulus {e}"
    );
    assert!(
        (rho - 990.0).abs() < 0.5 * (1100.0f64 - 990.0).abs(),
        "density {rho}"
    );

    // The fitted scenario loads, carries the record and reproduces a strike, with contact
    // stepped and held as the fit stepped and held it.
    assert_eq!(
        fit.overrides[..2],
        ["hold_contacts=true", "contact_substeps=5"]
    );
    assert_eq!(fit.contact_substeps, Some(5));
    assert!(fit.hold_contacts);
    let fitted = fit.document(&nominal, "strikes").unwrap();
    let loaded = fitted.loaded().unwrap();
    assert_eq!(loaded.scenario.integrator.contact_substeps, 5);
    assert!(loaded.scenario.integrator.hold_contacts);
    let record = loaded.calibration.expect("a [calibration] table");
    assert_eq!(record.recordings, Some(labels.len()));
    assert!(record
        .parameters
        .iter()
        .any(|p| p.key == "whisker.youngs_modulus" && p.determined && p.std_error.is_some()));
    let path = dir.join("fitted.toml");
    fitted.write(&path).unwrap();
    let reread = Document::load(path.to_str().unwrap(), &[]).unwrap();
    assert_eq!(
        reread.loaded().unwrap().scenario.sensor_response,
        loaded.scenario.sensor_response
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn recordings_of_the_nominal_whisker_leave_it_as_it_is() {
    let dir = folder("nominal");
    strikes(&dir, &[SHORT], &[(0.016, 0.5), (0.025, 1.1), (0.029, 0.7)]);
    let nominal = Document::load("e2", &[SHORT.to_string()]).unwrap();
    let set = read_labelled(&dir, &nominal, &Options::default()).unwrap();
    let fit = calibrate(&nominal, &set, &Settings::default(), &mut |_| {}).unwrap();
    let e = value(&fit, "whisker.youngs_modulus");
    assert!((e / 3.0e9 - 1.0).abs() < 0.01, "modulus {e}");
    let theta01 = fit.channels.iter().find(|c| c.name == "theta01").unwrap();
    assert!(theta01.rms_before < 1e-9, "{}", theta01.rms_before);
    // A follicle the recordings show to be clamped stays clamped.
    let follicle = fit
        .parameters
        .iter()
        .find(|p| p.key == "whisker.follicle.stiffness")
        .unwrap();
    assert!(
        !follicle.determined || follicle.value > 1e-2,
        "follicle {:?}",
        follicle
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_tip_thinner_than_the_tapered_nominal_in_a_soft_follicle_is_found() {
    // The user believes their whisker tapers to half its base radius in a clamped follicle; it
    // tapers to 0.35 of it and sits in a follicle 6 times as compliant as the nominal chain's
    // base joint. Both lie outside where a scan of the nominal's neighbourhood alone starts.
    let dir = folder("soft");
    let plain = Document::load("e2", &[SHORT.to_string()]).unwrap();
    let w = plain.loaded().unwrap().scenario;
    let tapered = format!("whisker.tip_radius={:?}", 0.5 * w.whisker.base_radius);
    let nominal = Document::load("e2", &[SHORT.to_string(), tapered.clone()]).unwrap();
    let base = nominal.loaded().unwrap().scenario;
    let checked = base.whisker.check().unwrap();
    let k0 = vibrissa_core::chain::Model::new(&checked, base.segments, base.discretisation)
        .unwrap()
        .stiffness[0];
    let (tip, stiffness) = (0.35 * w.whisker.base_radius, k0 / 6.0);
    let truth = [
        SHORT.to_string(),
        format!("whisker.tip_radius={tip:?}"),
        format!(
            "whisker.follicle={{ kind = \"spring\", stiffness = {stiffness:?}, damping = {:?} }}",
            1e-4 * stiffness
        ),
    ];
    let truth: Vec<&str> = truth.iter().map(String::as_str).collect();
    let labels = [
        (0.016, 0.4),
        (0.022, 0.9),
        (0.028, 1.4),
        (0.019, 1.2),
        (0.025, 0.6),
    ];
    strikes(&dir, &truth, &labels);
    let set = read_labelled(&dir, &nominal, &Options::default()).unwrap();
    let fit = calibrate(&nominal, &set, &Settings::default(), &mut |_| {}).unwrap();
    let found_tip = value(&fit, "whisker.tip_radius");
    let found_follicle = value(&fit, "whisker.follicle.stiffness");
    assert!(
        (found_tip / tip - 1.0).abs() < 0.1,
        "tip radius {found_tip}, truth {tip}"
    );
    assert!(
        (found_follicle / stiffness).ln().abs() < 0.5_f64.ln().abs(),
        "follicle stiffness {found_follicle}, truth {stiffness}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bad_settings_are_refused_before_any_simulation() {
    let dir = folder("settings");
    strikes(&dir, &[SHORT], &[(0.02, 0.6)]);
    let nominal = Document::load("e2", &[SHORT.to_string()]).unwrap();
    let set = read_labelled(&dir, &nominal, &Options::default()).unwrap();
    for settings in [
        Settings {
            gain_prior: f64::NAN,
            ..Settings::default()
        },
        Settings {
            max_iterations: 0,
            ..Settings::default()
        },
        Settings {
            step: 0.0,
            ..Settings::default()
        },
    ] {
        let err = calibrate(&nominal, &set, &settings, &mut |_| {}).unwrap_err();
        assert!(err.to_string().contains("calibration"), "{err}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A calibrated scenario file beside `dir` that names it as its labelled strikes (by its name
/// alone, so that it is found from the file's directory), with the short strikes' timing and
/// contact stepped and held as calibration writes it.
fn calibrated_file(dir: &Path) -> PathBuf {
    let name = dir.file_name().unwrap().to_str().unwrap();
    let path = dir.with_extension("toml");
    let text = format!(
        "experiment = \"e2\"\nduration = 0.08\ncontact_substeps = 5\nhold_contacts = true\n\n[calibration]\nlabelled = \"{name}\"\n\
         recordings = 1\nrms_before = {{}}\nrms_after = {{}}\nnoise = {{}}\nparameters = []\n"
    );
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn the_fit_s_residuals_are_what_its_strikes_differ_by_and_runs_carry_them() {
    use vibrissa_infer::experiment::{Noise, CHANNELS};
    use vibrissa_infer::model_error::ModelError;
    use vibrissa_infer::Family;
    // Strikes of the scenario's own whisker: nothing to add.
    let same = folder("residual-same");
    strikes(&same, &[SHORT], &[(0.018, 0.6), (0.027, 1.1)]);
    let family = Family::open(calibrated_file(&same).to_str().unwrap(), &[]).unwrap();
    assert_eq!(family.labelled_strikes(), Some(same.as_path()));
    let me = ModelError::of(&family, family.labelled_strikes().unwrap()).unwrap();
    assert_eq!(me.strikes(), 2);
    for (c, r) in me.rms().iter().enumerate() {
        assert!(*r < 1e-12, "{}: {r}", CHANNELS[c]);
    }

    // One strike of a whisker 15% stiffer: its residual, added to the scenario's run at its
    // labels, gives the strike back.
    let stiffer = folder("residual-stiffer");
    strikes(
        &stiffer,
        &[SHORT, "whisker.youngs_modulus=3.45e9"],
        &[(0.021, 0.8)],
    );
    let family = Family::open(calibrated_file(&stiffer).to_str().unwrap(), &[]).unwrap();
    let me = ModelError::of(&family, &stiffer).unwrap();
    assert!(me.rms()[1] > 1e-3, "theta12 residual {}", me.rms()[1]);
    let recorded = vibrissa_io::series::read_csv(stiffer.join("strike0.csv")).unwrap();
    let run = family
        .with_model_error(Some(std::sync::Arc::new(me)))
        .simulate(&[0.021, 0.8], &Noise::NONE, 3)
        .unwrap();
    for (c, name) in CHANNELS.iter().enumerate() {
        let want = recorded.column(name).unwrap();
        for (got, want) in run.series[c].iter().zip(want) {
            assert!(
                (got - want).abs() <= 1e-12 * (1.0 + want.abs()),
                "{name}: {got} against {want}"
            );
        }
    }
    // The nominal family adds nothing.
    let plain = family
        .nominal()
        .simulate(&[0.021, 0.8], &Noise::NONE, 3)
        .unwrap();
    assert!(plain.series[1]
        .iter()
        .zip(recorded.column("theta12").unwrap())
        .any(|(a, b)| (a - b).abs() > 1e-4));
    for dir in [same, stiffer] {
        let _ = std::fs::remove_file(dir.with_extension("toml"));
        let _ = std::fs::remove_dir_all(&dir);
    }
}

#[test]
fn contact_is_stepped_at_twenty_microseconds_unless_the_file_says_how() {
    let resolution = |sets: &[&str]| {
        let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
        contact_resolution(&Document::load("e2", &sets).unwrap()).unwrap()
    };
    // The default 0.1 ms step: five substeps near contact.
    assert_eq!(resolution(&[]), Some(5));
    // A long step takes as many as 20 µs needs; a step already that fine none.
    assert_eq!(resolution(&["dt=1e-3"]), Some(50));
    assert_eq!(resolution(&["dt=1e-5"]), None);
    assert_eq!(resolution(&["dt=2e-5"]), None);
    // A file (or override) that names the setting is left as it says, even at 1.
    assert_eq!(resolution(&["contact_substeps=1"]), None);
    assert_eq!(resolution(&["contact_substeps=3"]), None);
}

#[test]
fn a_file_that_names_its_contact_substeps_is_fitted_with_them() {
    let dir = folder("named-substeps");
    strikes(&dir, &[SHORT], &[(0.017, 0.6), (0.026, 1.2)]);
    let nominal =
        Document::load("e2", &[SHORT.to_string(), "contact_substeps=1".to_string()]).unwrap();
    let set = read_labelled(&dir, &nominal, &Options::default()).unwrap();
    let fit = calibrate(&nominal, &set, &Settings::default(), &mut |_| {}).unwrap();
    assert!(
        fit.overrides
            .iter()
            .all(|o| !o.starts_with("contact_substeps")),
        "{:?}",
        fit.overrides
    );
    assert_eq!(fit.contact_substeps, None);
    let fitted = fit.document(&nominal, "strikes").unwrap();
    assert_eq!(
        fitted
            .loaded()
            .unwrap()
            .scenario
            .integrator
            .contact_substeps,
        1
    );
    let _ = std::fs::remove_dir_all(&dir);
}
