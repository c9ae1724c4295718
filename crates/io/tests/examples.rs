//! Every example scenario under examples/scenarios loads.

use std::path::PathBuf;
use vibrissa_core::objects::Shape;
use vibrissa_core::sim::BaseDrive;
use vibrissa_core::whisker::Follicle;
use vibrissa_io::scenario::{experiment_box, load_full, Experiment};

fn folder() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../examples/scenarios")
}

#[test]
fn every_example_loads() {
    let mut names = Vec::new();
    for entry in std::fs::read_dir(folder()).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "toml") {
            if let Err(e) = load_full(path.to_str().unwrap(), &[]) {
                panic!("{e}");
            }
            names.push(path.file_stem().unwrap().to_string_lossy().into_owned());
        }
    }
    for expected in [
        "e2_d23_v06",
        "peg_whisk",
        "wall_ramp",
        "polygon_friction",
        "rat_curved",
        "pluck",
        "array_row",
        "peg_past",
    ] {
        assert!(
            names.iter().any(|n| n == expected),
            "{expected} missing from {names:?}"
        );
    }
}

/// Loads one example.
fn example(name: &str) -> vibrissa_io::scenario::Loaded {
    load_full(folder().join(name).to_str().unwrap(), &[]).unwrap()
}

#[test]
fn examples_say_what_their_names_say() {
    let e2 = example("e2_d23_v06.toml");
    let run = e2.experiment.unwrap();
    assert_eq!((run.experiment, run.d, run.v), (Experiment::E2, 0.023, 0.6));
    assert_eq!(e2.scenario.objects, vec![experiment_box(0.023, 0.6)]);

    let peg = example("peg_whisk.toml").scenario;
    assert_eq!(peg.objects[0].shape, Shape::Circle { radius: 0.001 });
    assert!(
        matches!(peg.base, BaseDrive::Sinusoid { amplitude, frequency, .. } if amplitude == 0.3 && frequency == 5.0)
    );

    let wall = example("wall_ramp.toml").scenario;
    assert_eq!(wall.objects[0].shape, Shape::Wall);
    assert!(matches!(wall.base, BaseDrive::Ramp { .. }));

    let poly = example("polygon_friction.toml").scenario;
    assert!(matches!(poly.objects[0].shape, Shape::Polygon { .. }));
    assert_eq!(poly.objects[0].friction, 0.3);

    let rat = example("rat_curved.toml").scenario;
    assert!(rat.whisker.rest_curvature > 0.0);
    assert!(matches!(rat.whisker.follicle, Follicle::Spring { .. }));
    assert!(rat.process_noise > 0.0);

    let traj = example("whisk_trajectory.toml").scenario;
    assert!(matches!(traj.base, BaseDrive::Trajectory { ref t, .. } if t.len() == 21));
}

#[test]
fn every_example_runs_and_touches_its_object() {
    for entry in std::fs::read_dir(folder()).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "toml") {
            continue;
        }
        let loaded = load_full(path.to_str().unwrap(), &[]).unwrap();
        let out = vibrissa_core::sim::run(&loaded.scenario, &mut |_| {})
            .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let name = path.display();
        assert!(
            out.rows
                .iter()
                .all(|r| r[..6].iter().all(|x| x.is_finite())),
            "{name}"
        );
        if !loaded.scenario.objects.is_empty() {
            assert!(out.rows.iter().any(|r| r[6] > 0.5), "{name}: no contact");
            assert!(
                out.max_penetration < 1e-6,
                "{name}: {}",
                out.max_penetration
            );
        }
    }
}
