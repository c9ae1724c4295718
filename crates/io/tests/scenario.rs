//! Scenario files: the schema, built-ins, overrides and error messages.

use std::f64::consts::PI;
use std::fs;
use std::path::PathBuf;
use vibrissa_core::chain::Discretisation;
use vibrissa_core::objects::{Motion, Shape};
use vibrissa_core::sim::{BaseDrive, Scenario};
use vibrissa_core::whisker::{Damping, Follicle, WhiskerParams};
use vibrissa_io::scenario::{self, builtin, experiment_box, load_full, Experiment, BUILTINS};
use vibrissa_io::{load, load_str, Error};

fn sets(items: &[&str]) -> Vec<String> {
    items.iter().map(|s| s.to_string()).collect()
}

/// The message of a load that must fail.
fn load_err(text: &str, set: &[&str]) -> String {
    match load_str(text, "test.toml", &sets(set)) {
        Ok(s) => panic!("expected an error, loaded {s:?}"),
        Err(e) => e.to_string(),
    }
}

/// A fresh folder for this test's files.
fn temp_dir(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("scenario-{name}"));
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn builtins_are_the_seed_experiments() {
    for name in BUILTINS {
        let text = builtin(name).unwrap();
        assert!(text.contains(&format!("experiment = \"{name}\"")));
        let loaded = load_full(name, &[]).unwrap();
        let s = &loaded.scenario;
        // docs/experiments.md: w30, 150 ms at 1 kHz; this project's N = 20 and dt = 0.1 ms.
        assert_eq!(s.whisker, WhiskerParams::w30());
        assert_eq!(s.segments, 20);
        assert_eq!(s.duration, 0.15);
        assert_eq!(s.sample_rate, 1000.0);
        assert_eq!(s.integrator.dt, 1e-4);
        assert_eq!(s.base, BaseDrive::Fixed);
        assert_eq!(s.objects, vec![experiment_box(0.020, 0.6)]);
        let run = loaded.experiment.unwrap();
        assert_eq!(run.experiment.name(), name);
        assert_eq!((run.d, run.v), (0.020, 0.6));
    }
    assert!(builtin("e3").is_none());
}

#[test]
fn builtins_are_families_with_the_seed_templates_and_grids() {
    let e1 = load_full("e1", &[]).unwrap().family.unwrap();
    assert_eq!(e1.keys(), ["d"]);
    assert_eq!(e1.templates, [vec![0.015, 0.023, 0.030]]);
    assert_eq!(e1.grid[0].len(), 16);
    let e2 = load_full("e2", &[]).unwrap().family.unwrap();
    assert_eq!(e2.keys(), ["d", "v"]);
    assert_eq!(e2.unknowns[1].range, [0.3, 1.5]);
    assert_eq!(e2.unknowns[0].margin, [0.001, 0.0]);
    assert_eq!(e2.templates[1], [0.3, 0.9, 1.5]);
    assert_eq!(e2.grid[0].len() * e2.grid[1].len(), 80);
    assert_eq!(e2.grid[0][7], 0.022);
    // A file that names an experiment and no unknowns is that experiment's family.
    let nominal = load_str(
        "experiment = \"e2\"\n[whisker]\nyoungs_modulus = 3.3e9\n",
        "nominal.toml",
        &[],
    );
    assert!(nominal.is_ok());
    let dir = temp_dir("nominal-family");
    let path = dir.join("nominal.toml");
    fs::write(&path, "experiment = \"e2\"\n").unwrap();
    let loaded = load_full(path.to_str().unwrap(), &[]).unwrap();
    assert_eq!(loaded.family.unwrap(), e2);
    assert_eq!(Experiment::E2.name(), "e2");
}

#[test]
fn a_family_makes_the_run_at_any_values_of_its_unknowns() {
    let dir = temp_dir("family-values");
    let path = dir.join("stiff.toml");
    fs::write(
        &path,
        "experiment = \"e1\"\n[unknowns]\nwhisker.youngs_modulus = [2e9, 4e9]\n\"objects.0.friction\" = { range = [0, 0.5] }\n[[objects]]\nshape = \"circle\"\nradius = 0.001\nposition = [0.01, 0.01]\n",
    )
    .unwrap();
    let (doc, loaded) = scenario::open(path.to_str().unwrap(), &[]).unwrap();
    let family = loaded.family.unwrap();
    assert_eq!(
        family.keys(),
        ["whisker.youngs_modulus", "objects.0.friction"]
    );
    // Defaults: templates at the ends and middle, six grid values, margins of 1/12 the width.
    assert_eq!(family.templates[0], [2e9, 3e9, 4e9]);
    assert_eq!(family.grid[1], [0.0, 0.1, 0.2, 0.3, 0.4, 0.5]);
    assert!((family.unknowns[0].margin[1] - 2e9 / 12.0).abs() < 1.0);
    let run = doc
        .with_values(&[
            ("whisker.youngs_modulus", 2.5e9),
            ("objects.0.friction", 0.25),
        ])
        .unwrap();
    assert_eq!(run.scenario.whisker.youngs_modulus, 2.5e9);
    assert_eq!(run.scenario.objects[0].friction, 0.25);
    assert_eq!(
        run.scenario.objects.len(),
        2,
        "the file's peg, then the experiment's box"
    );
    assert_eq!(
        doc.digest(),
        scenario::open(path.to_str().unwrap(), &[])
            .unwrap()
            .0
            .digest()
    );
    // A value the schema refuses names the key and the values.
    let err = doc
        .with_values(&[("whisker.youngs_modulus", -1.0)])
        .unwrap_err()
        .to_string();
    assert!(err.contains("youngs_modulus"), "{err}");
}

#[test]
fn malformed_families_are_refused_by_name() {
    let cases: [(&str, &str); 7] = [
        ("[unknowns]\nd = [0.03, 0.015]\n", "lo < hi"),
        ("[unknowns]\nd = [0.015]\n", "expected two"),
        ("[unknowns]\nd = \"wide\"\n", "array of numbers"),
        (
            "[unknowns]\nd = [0.015, 0.03]\n[templates]\nv = [1]\n",
            "names no unknown",
        ),
        (
            "[unknowns]\nd = [0.015, 0.03]\n[grid]\nd = [0.04]\n",
            "outside the unknown's range",
        ),
        ("[templates]\nd = [0.02]\n", "needs an [unknowns] table"),
        (
            "[unknowns]\nd = { range = [0.015, 0.03], step = 1 }\n",
            "takes range, margin and name",
        ),
    ];
    for (body, expected) in cases {
        let text = format!("experiment = \"e2\"\n{body}");
        let err = load_err(&text, &[]);
        assert!(err.contains(expected), "{body}: {err}");
        assert!(err.contains("test.toml"), "{err}");
    }
    // A key the schema does not know is refused when the family is opened.
    let dir = temp_dir("family-bad-key");
    let path = dir.join("bad.toml");
    fs::write(
        &path,
        "experiment = \"e2\"\n[unknowns]\nwhisker.modulus = [1e9, 2e9]\n",
    )
    .unwrap();
    let err = scenario::open(path.to_str().unwrap(), &[])
        .unwrap_err()
        .to_string();
    assert!(err.contains("modulus"), "{err}");
}

/// The family of a file that must load.
fn family_of(text: &str) -> scenario::FamilySpec {
    let (_, loaded) = scenario::open_str(text, "test.toml", &[]).unwrap();
    loaded.family.unwrap()
}

/// A peg whose position is an unknown: the file for `unknowns` (and more tables after them).
fn peg_family(unknowns: &str) -> String {
    format!(
        "[[objects]]\nshape = \"circle\"\nradius = 0.001\nposition = [0.02, 0.01]\n[unknowns]\n{unknowns}"
    )
}

#[test]
fn an_unknown_may_be_named() {
    let family = family_of(&peg_family(
        "\"objects.0.position.0\" = { range = [0.018, 0.030], name = \"x\" }\n\
         \"objects.0.position.1\" = [0.005, 0.015]\n",
    ));
    assert_eq!(
        family.keys(),
        ["objects.0.position.0", "objects.0.position.1"]
    );
    // An unnamed unknown is named by its key.
    assert_eq!(family.names(), ["x", "objects.0.position.1"]);
    assert_eq!(family.unknowns[0].name, "x");
    assert_eq!(family.unknowns[0].range, [0.018, 0.030]);
    assert_eq!(family.unknowns[1].name, family.unknowns[1].key);

    // The longest name and every allowed character.
    let long = "a".repeat(32);
    let family = family_of(&peg_family(&format!(
        "\"objects.0.position.0\" = {{ range = [0.018, 0.030], name = \"{long}\" }}\n\
         \"objects.0.position.1\" = {{ range = [0.005, 0.015], name = \"Y_1.b-2\" }}\n"
    )));
    assert_eq!(family.names(), [long.as_str(), "Y_1.b-2"]);
}

#[test]
fn templates_and_grids_take_an_unknown_by_key_or_name() {
    let unknowns = "\"objects.0.position.0\" = { range = [0.018, 0.030], name = \"x\" }\n\
                    \"objects.0.position.1\" = { range = [0.005, 0.015], name = \"y\" }\n";
    let family = family_of(&format!(
        "{}[templates]\nx = [0.018, 0.030]\n\"objects.0.position.1\" = [0.01]\n\
         [grid]\nobjects.0.position.0 = [0.02]\ny = [0.005, 0.015]\n",
        peg_family(unknowns)
    ));
    assert_eq!(family.templates, [vec![0.018, 0.030], vec![0.01]]);
    assert_eq!(family.grid, [vec![0.02], vec![0.005, 0.015]]);

    // Both spellings for one unknown are refused, naming it.
    let e = load_err(
        &format!(
            "{}[grid]\nx = [0.02]\n\"objects.0.position.0\" = [0.02]\ny = [0.01]\n",
            peg_family(unknowns)
        ),
        &[],
    );
    assert!(e.contains("`grid.x`") && e.contains("given twice"), "{e}");
    // A name that is no unknown's lists the keys with their names.
    let e = load_err(
        &format!("{}[templates]\nz = [0.02]\n", peg_family(unknowns)),
        &[],
    );
    assert!(
        e.contains("`templates.z` names no unknown")
            && e.contains("objects.0.position.0 (named x)"),
        "{e}"
    );
    // A missing one says it may be given by its name.
    let e = load_err(
        &format!("{}[templates]\nx = [0.02]\n", peg_family(unknowns)),
        &[],
    );
    assert!(
        e.contains("`templates.objects.0.position.1` is missing") && e.contains("`y`"),
        "{e}"
    );
    // Errors in values name the spelling the file used.
    let e = load_err(
        &format!("{}[grid]\nx = [0.5]\ny = [0.01]\n", peg_family(unknowns)),
        &[],
    );
    assert!(e.contains("`grid.x` holds 0.5"), "{e}");
}

#[test]
fn bad_or_clashing_names_are_refused_by_field() {
    let x = "\"objects.0.position.0\"";
    let y = "\"objects.0.position.1\"";
    let cases = [
        // The same name twice.
        (
            format!("{x} = {{ range = [0.018, 0.030], name = \"p\" }}\n{y} = {{ range = [0.005, 0.015], name = \"p\" }}\n"),
            "`unknowns.objects.0.position.1.name`",
            "distinct",
        ),
        // A name that is another unknown's key.
        (
            format!("{x} = {{ range = [0.018, 0.030], name = \"objects.0.position.1\" }}\n{y} = [0.005, 0.015]\n"),
            "`unknowns.objects.0.position.0.name`",
            "the key of another unknown",
        ),
        // Characters outside the allowed set.
        (
            format!("{x} = {{ range = [0.018, 0.030], name = \"x pos\" }}\n"),
            "`unknowns.objects.0.position.0.name`",
            "ASCII letters, digits",
        ),
        (
            format!("{x} = {{ range = [0.018, 0.030], name = \"x\u{e9}\" }}\n"),
            "`unknowns.objects.0.position.0.name`",
            "ASCII letters, digits",
        ),
        // Empty, too long, not a string.
        (
            format!("{x} = {{ range = [0.018, 0.030], name = \"\" }}\n"),
            "`unknowns.objects.0.position.0.name`",
            "1 to 32",
        ),
        (
            format!("{x} = {{ range = [0.018, 0.030], name = \"{}\" }}\n", "a".repeat(33)),
            "`unknowns.objects.0.position.0.name`",
            "33 characters",
        ),
        (
            format!("{x} = {{ range = [0.018, 0.030], name = 7 }}\n"),
            "`unknowns.objects.0.position.0.name`",
            "as a string",
        ),
    ];
    for (unknowns, field, message) in cases {
        let e = load_err(&peg_family(&unknowns), &[]);
        assert!(e.contains(field) && e.contains(message), "{unknowns}: {e}");
    }
    // One key given twice, quoted and nested, is refused rather than named twice.
    let e = load_err(
        &peg_family("\"objects.0.friction\" = [0, 0.5]\nobjects.0.friction = [0, 0.4]\n"),
        &[],
    );
    assert!(
        e.contains("`unknowns.objects.0.friction` is given twice"),
        "{e}"
    );
}

#[test]
fn experiment_box_geometry() {
    let b = experiment_box(0.023, 0.9);
    assert_eq!(
        b.shape,
        Shape::Box {
            width: 0.010,
            height: 0.010
        }
    );
    // Top-left corner at (d, -1 mm): centre at (d + 5 mm, -6 mm).
    assert!((b.position[0] - 0.028).abs() < 1e-15);
    assert!((b.position[1] + 0.006).abs() < 1e-15);
    assert_eq!(b.angle, 0.0);
    assert_eq!(b.friction, 0.0);
    assert_eq!(
        b.motion,
        Motion::Constant {
            velocity: [0.0, 0.9],
            angular_velocity: 0.0
        }
    );
    // The pose at t = 0.1 s has moved 90 mm along +y.
    let p = b.pose(0.1);
    assert!((p.position[1] - (-0.006 + 0.09)).abs() < 1e-15);
}

#[test]
fn builtin_overrides_set_d_and_v() {
    let loaded = load_full("e2", &sets(&["d=0.015", "v=1.5", "seed=3"])).unwrap();
    assert_eq!(loaded.scenario.objects, vec![experiment_box(0.015, 1.5)]);
    assert_eq!(loaded.scenario.seed, 3);
    let run = loaded.experiment.unwrap();
    assert_eq!((run.experiment, run.d, run.v), (Experiment::E2, 0.015, 1.5));
    assert!(loaded.origin.contains("e2"));
}

#[test]
fn experiment_in_a_file_defaults_d_and_v_and_appends_its_box() {
    let text = r#"
experiment = "e1"
[[objects]]
shape = "circle"
radius = 0.001
position = [0.01, 0.01]
"#;
    let s = load_str(text, "test.toml", &[]).unwrap();
    assert_eq!(s.objects.len(), 2);
    assert_eq!(s.objects[0].shape, Shape::Circle { radius: 0.001 });
    assert_eq!(s.objects[1], experiment_box(0.020, 0.6));
}

#[test]
fn empty_file_is_the_default_scenario() {
    assert_eq!(
        load_str("", "empty.toml", &[]).unwrap(),
        Scenario::default()
    );
}

#[test]
fn every_key_maps_to_the_scenario() {
    let text = r#"
duration = 0.2
dt = 5e-5
rho_inf = 0.9
tolerance = 1e-6
max_iterations = 5
sample_rate = 2000
seed = 42
segments = 30
discretisation = "trapezoid"
process_noise = 1e-6

[whisker]
preset = "rat"
length = 0.04
base_radius = 8e-5
tip_radius = 1e-5
rest_curvature = 10.0
youngs_modulus = 4e9
density = 1200
follicle = { kind = "spring", stiffness = 3e-5, damping = 2e-8 }
damping = { kind = "segment_q", q = 12.0 }

[sensor_noise]
theta01 = 0.001
theta12 = 0.002
m0 = 1e-9
fx = 1e-6
fy = 2e-6

[base]
kind = "ramp"
rate = 2.0
start = 0.01

[[objects]]
shape = "box"
width = 0.01
height = 0.005
position = [0.02, -0.01]
angle = 0.1
friction = 0.3
velocity = [0.1, 0.5]
angular_velocity = 1.0

[[objects]]
shape = "polygon"
vertices = [[0, 0], [0.002, 0], [0, 0.002]]
waypoints = [[0, 0.01, -0.005, 0], [0.1, 0.012, 0.005, 0.5]]

[[objects]]
shape = "wall"
position = [0, 0.01]
angle = 3.141592653589793
"#;
    let s = load_str(text, "full.toml", &[]).unwrap();
    assert_eq!(s.duration, 0.2);
    assert_eq!(s.integrator.dt, 5e-5);
    assert_eq!(s.integrator.rho_inf, 0.9);
    assert_eq!(s.integrator.tolerance, 1e-6);
    assert_eq!(s.integrator.max_iterations, 5);
    assert_eq!(s.sample_rate, 2000.0);
    assert_eq!(s.seed, 42);
    assert_eq!(s.segments, 30);
    assert_eq!(s.discretisation, Discretisation::Trapezoid);
    assert_eq!(s.process_noise, 1e-6);

    let w = &s.whisker;
    assert_eq!(
        (
            w.length,
            w.base_radius,
            w.tip_radius,
            w.rest_curvature,
            w.youngs_modulus,
            w.density
        ),
        (0.04, 8e-5, 1e-5, 10.0, 4e9, 1200.0)
    );
    assert_eq!(
        w.follicle,
        Follicle::Spring {
            stiffness: 3e-5,
            damping: 2e-8
        }
    );
    assert_eq!(w.damping, Damping::SegmentQ { q: 12.0 });

    let n = &s.sensor_noise;
    assert_eq!(
        (n.theta01, n.theta12, n.m0, n.fx, n.fy),
        (0.001, 0.002, 1e-9, 1e-6, 2e-6)
    );

    // Ramp defaults: never stops, 5 ms corners.
    assert_eq!(
        s.base,
        BaseDrive::Ramp {
            rate: 2.0,
            start: 0.01,
            stop: f64::INFINITY,
            smoothing: 0.005
        }
    );

    assert_eq!(s.objects.len(), 3);
    let b = &s.objects[0];
    assert_eq!(
        b.shape,
        Shape::Box {
            width: 0.01,
            height: 0.005
        }
    );
    assert_eq!((b.position, b.angle, b.friction), ([0.02, -0.01], 0.1, 0.3));
    assert_eq!(
        b.motion,
        Motion::Constant {
            velocity: [0.1, 0.5],
            angular_velocity: 1.0
        }
    );
    // Waypoints: the initial pose is the first waypoint's; friction defaults to 0.
    let p = &s.objects[1];
    assert_eq!(
        (p.position, p.angle, p.friction),
        ([0.01, -0.005], 0.0, 0.0)
    );
    assert_eq!(
        p.motion,
        Motion::Waypoints {
            points: vec![[0.0, 0.01, -0.005, 0.0], [0.1, 0.012, 0.005, 0.5]]
        }
    );
    assert_eq!(s.objects[2].shape, Shape::Wall);
    assert_eq!(s.objects[2].angle, PI);
}

#[test]
fn sinusoid_and_fixed_base() {
    let s = load_str(
        "[base]\nkind = \"sinusoid\"\namplitude = 0.3\nfrequency = 8\n",
        "t.toml",
        &[],
    )
    .unwrap();
    assert_eq!(
        s.base,
        BaseDrive::Sinusoid {
            amplitude: 0.3,
            frequency: 8.0,
            phase: 0.0,
            offset: 0.0
        }
    );
    let s = load_str("[base]\nkind = \"fixed\"\n", "t.toml", &[]).unwrap();
    assert_eq!(s.base, BaseDrive::Fixed);
}

#[test]
fn whisker_table_without_preset_overrides_w30() {
    let s = load_str("[whisker]\nlength = 0.04\n", "t.toml", &[]).unwrap();
    let mut expected = WhiskerParams::w30();
    expected.length = 0.04;
    assert_eq!(s.whisker, expected);
}

#[test]
fn unknown_key_names_file_line_and_allowed_keys() {
    let e = load_err("duration = 0.1\n[whisker]\nlenght = 0.03\n", &[]);
    assert!(e.starts_with("test.toml: "), "{e}");
    assert!(e.contains("line 3, column 1"), "{e}");
    assert!(e.contains("unknown field `lenght`"), "{e}");
    assert!(
        e.contains("`length`") && e.contains("`youngs_modulus`"),
        "{e}"
    );

    let e = load_err("durration = 0.1\n", &[]);
    assert!(
        e.contains("line 1") && e.contains("`durration`") && e.contains("`duration`"),
        "{e}"
    );
}

#[test]
fn wrong_type_and_bad_choice_name_the_place() {
    let e = load_err("seed = 1\nduration = \"long\"\n", &[]);
    assert!(
        e.contains("test.toml") && e.contains("line 2, column 12"),
        "{e}"
    );
    assert!(e.contains("expected f64"), "{e}");

    let e = load_err("discretisation = \"exact\"\n", &[]);
    assert!(
        e.contains("line 1") && e.contains("`gregory`") && e.contains("`seed`"),
        "{e}"
    );

    let e = load_err("[[objects]]\nshape = \"cone\"\nposition = [0, 0]\n", &[]);
    assert!(e.contains("line 2") && e.contains("`polygon`"), "{e}");

    let e = load_err("experiment = \"e3\"\n", &[]);
    assert!(e.contains("`e1`") && e.contains("`e2`"), "{e}");

    // Syntax errors too.
    let e = load_err("duration = \n", &[]);
    assert!(e.contains("test.toml") && e.contains("line 1"), "{e}");
}

#[test]
fn keys_of_the_wrong_kind_are_named() {
    let e = load_err(
        "[[objects]]\nshape = \"box\"\nwidth = 0.01\nheight = 0.01\nradius = 0.01\nposition = [0, 0]\n",
        &[],
    );
    assert!(e.contains("`objects[0].radius`"), "{e}");
    assert!(
        e.contains("shape = \"box\"") && e.contains("width, height"),
        "{e}"
    );

    let e = load_err("[[objects]]\nshape = \"circle\"\nposition = [0, 0]\n", &[]);
    assert!(e.contains("`objects[0].radius` is required"), "{e}");

    let e = load_err("[[objects]]\nshape = \"circle\"\nradius = 0.001\n", &[]);
    assert!(e.contains("`objects[0].position` is required"), "{e}");

    let e = load_err(
        "[[objects]]\nshape = \"wall\"\nposition = [0, 0]\nwaypoints = [[0, 0, 0, 0]]\n",
        &[],
    );
    assert!(
        e.contains("`objects[0].position`") && e.contains("waypoints"),
        "{e}"
    );

    let e = load_err("[base]\nkind = \"sinusoid\"\namplitude = 0.3\n", &[]);
    assert!(e.contains("`base.frequency` is required"), "{e}");

    let e = load_err(
        "[base]\nkind = \"sinusoid\"\namplitude = 0.3\nfrequency = 5\nrate = 1\n",
        &[],
    );
    assert!(e.contains("`base.rate` does not apply"), "{e}");

    let e = load_err("[base]\nkind = \"fixed\"\namplitude = 0.3\n", &[]);
    assert!(e.contains("`base.amplitude`"), "{e}");

    let e = load_err(
        "[whisker]\nfollicle = { kind = \"spring\", stiffness = 1e-5 }\n",
        &[],
    );
    assert!(e.contains("`whisker.follicle.damping` is required"), "{e}");

    let e = load_err(
        "[whisker]\nfollicle = { kind = \"clamped\", stiffness = 1e-5 }\n",
        &[],
    );
    assert!(
        e.contains("`whisker.follicle.stiffness` does not apply"),
        "{e}"
    );

    let e = load_err(
        "[whisker]\ndamping = { kind = \"modal_ratio\", q = 10 }\n",
        &[],
    );
    assert!(
        e.contains("`whisker.damping.q`") && e.contains("ratio"),
        "{e}"
    );

    let e = load_err(
        "[whisker]\nfollicle = { kind = \"spring\", stiffness = 1, damping = 0, extra = 1 }\n",
        &[],
    );
    assert!(e.contains("unknown field `extra`"), "{e}");

    let e = load_err("d = 0.02\n", &[]);
    assert!(e.contains("`d`") && e.contains("experiment"), "{e}");
}

#[test]
fn out_of_range_values_are_cores_verdict_with_the_file() {
    let e = load_str("[whisker]\nlength = -0.03\n", "bad.toml", &[]).unwrap_err();
    assert!(matches!(
        e.core(),
        Some(vibrissa_core::Error::InvalidParameter { .. })
    ));
    let e = e.to_string();
    assert!(
        e.starts_with("bad.toml: ") && e.contains("whisker.length"),
        "{e}"
    );

    let e = load_err("[whisker]\npreset = \"cat\"\n", &[]);
    assert!(e.contains("whisker.preset") && e.contains("w30"), "{e}");

    let e = load_err("duration = 0\n", &[]);
    assert!(e.contains("duration"), "{e}");

    let e = load_err("dt = 0.01\n", &[]);
    assert!(e.contains("dt"), "{e}");

    let e = load_err(
        "[[objects]]\nshape = \"box\"\nwidth = 0.01\nheight = -1\nposition = [0, 0]\n",
        &[],
    );
    assert!(e.contains("objects[0].height"), "{e}");

    let e = load_err("[[objects]]\nshape = \"polygon\"\nvertices = [[0, 0], [0, 1], [1, 0]]\nposition = [0, 0]\n", &[]);
    assert!(
        e.contains("objects[0].vertices") && e.contains("counter-clockwise"),
        "{e}"
    );

    let e = load_err("experiment = \"e2\"\nd = nan\n", &[]);
    assert!(e.contains("invalid d"), "{e}");
}

/// The shape of the one object of a file that must load.
fn shape_of(object: &str) -> Shape {
    let s = load_str(
        &format!("[[objects]]\n{object}\nposition = [0.02, 0.0]\n"),
        "test.toml",
        &[],
    )
    .unwrap();
    s.objects[0].shape.clone()
}

#[test]
fn a_square_is_a_box_of_equal_sides() {
    assert_eq!(
        shape_of("shape = \"square\"\nside = 0.004"),
        Shape::Box {
            width: 0.004,
            height: 0.004
        }
    );
}

#[test]
fn a_triangle_is_equilateral_about_its_centroid() {
    let side = 0.006;
    let Shape::Polygon { vertices: v } = shape_of("shape = \"triangle\"\nside = 0.006") else {
        panic!("a triangle is a polygon");
    };
    assert_eq!(v.len(), 3);
    let tol = 1e-15;
    // Centroid at the origin, the first vertex on +y.
    let centroid = [0, 1].map(|c| v.iter().map(|p| p[c]).sum::<f64>() / 3.0);
    assert!(
        centroid[0].abs() < tol && centroid[1].abs() < tol,
        "{centroid:?}"
    );
    assert_eq!(v[0][0], 0.0);
    assert!(v[0][1] > 0.0);
    // Every side as given.
    for k in 0..3 {
        let (a, b) = (v[k], v[(k + 1) % 3]);
        let length = (b[0] - a[0]).hypot(b[1] - a[1]);
        assert!((length - side).abs() < tol, "side {k}: {length}");
    }
    // Counter-clockwise: positive signed area, that of an equilateral triangle.
    let area = 0.5
        * (0..3)
            .map(|k| {
                let (a, b) = (v[k], v[(k + 1) % 3]);
                a[0] * b[1] - b[0] * a[1]
            })
            .sum::<f64>();
    assert!(
        (area - 3f64.sqrt() / 4.0 * side * side).abs() < tol,
        "{area}"
    );
}

#[test]
fn a_side_must_be_positive_and_belongs_to_squares_and_triangles() {
    for shape in ["square", "triangle"] {
        for side in ["-0.004", "0", "nan", "inf"] {
            let e = load_err(
                &format!("[[objects]]\nshape = \"{shape}\"\nside = {side}\nposition = [0, 0]\n"),
                &[],
            );
            assert!(
                e.contains("objects[0].side") && e.contains("> 0"),
                "{shape}, {side}: {e}"
            );
        }
        let e = load_err(
            &format!("[[objects]]\nshape = \"{shape}\"\nposition = [0, 0]\n"),
            &[],
        );
        assert!(e.contains("`objects[0].side` is required"), "{e}");
        let e = load_err(
            &format!(
                "[[objects]]\nshape = \"{shape}\"\nside = 0.01\nwidth = 0.01\nposition = [0, 0]\n"
            ),
            &[],
        );
        assert!(
            e.contains("`objects[0].width` does not apply") && e.contains("takes side"),
            "{e}"
        );
    }
    for other in [
        "shape = \"circle\"\nradius = 0.001",
        "shape = \"box\"\nwidth = 0.01\nheight = 0.01",
        "shape = \"polygon\"\nvertices = [[0, 0], [0.002, 0], [0, 0.002]]",
        "shape = \"wall\"",
    ] {
        let e = load_err(
            &format!("[[objects]]\n{other}\nside = 0.01\nposition = [0, 0]\n"),
            &[],
        );
        assert!(
            e.contains("`objects[0].side` does not apply"),
            "{other}: {e}"
        );
    }
    // A side may be set like any key.
    let s = load_str(
        "[[objects]]\nshape = \"square\"\nside = 0.004\nposition = [0.02, 0]\n",
        "test.toml",
        &sets(&["objects.0.side=0.008"]),
    )
    .unwrap();
    assert_eq!(
        s.objects[0].shape,
        Shape::Box {
            width: 0.008,
            height: 0.008
        }
    );
}

#[test]
fn overrides_set_nested_keys_and_array_elements() {
    let text = r#"
[[objects]]
shape = "circle"
radius = 0.001
position = [0.02, 0.004]
"#;
    let s = load_str(
        text,
        "t.toml",
        &sets(&[
            "whisker.length=0.04",
            "whisker.preset=rat",
            "objects.0.friction=0.3",
            "objects.0.velocity=[0, 0.6]",
            "objects.1.shape=wall",
            "objects.1.position=[0, 0.01]",
            "segments = 40",
            "discretisation=seed",
            "base.kind=ramp",
            "base.rate=1",
            "base.stop=inf",
        ]),
    )
    .unwrap();
    let mut rat = WhiskerParams::rat();
    rat.length = 0.04;
    assert_eq!(s.whisker, rat);
    assert_eq!(s.segments, 40);
    assert_eq!(s.discretisation, Discretisation::Seed);
    assert_eq!(s.objects[0].friction, 0.3);
    assert_eq!(
        s.objects[0].motion,
        Motion::Constant {
            velocity: [0.0, 0.6],
            angular_velocity: 0.0
        }
    );
    assert_eq!(s.objects[1].shape, Shape::Wall);
    assert_eq!(s.objects[1].position, [0.0, 0.01]);
    assert!(
        matches!(s.base, BaseDrive::Ramp { rate, stop, .. } if rate == 1.0 && stop.is_infinite())
    );

    // Later overrides win.
    let s = load("e2", &sets(&["d=0.02", "d=0.03"])).unwrap();
    assert_eq!(s.objects[0], experiment_box(0.03, 0.6));
}

#[test]
fn bad_overrides_are_errors() {
    // No `=`.
    let e = load_err("", &["whisker.length"]);
    assert!(
        e.contains("--set `whisker.length`") && e.contains("key=value"),
        "{e}"
    );
    // Empty key part.
    let e = load_err("", &["whisker..length=1"]);
    assert!(e.contains("whisker..length"), "{e}");
    // A key that the schema does not have: caught when the document is read.
    let e = load_err("", &["whisker.lenght=0.04"]);
    assert!(
        e.contains("unknown field `lenght`") && e.contains("whisker"),
        "{e}"
    );
    assert!(e.contains("--set whisker.lenght=0.04"), "{e}");
    let e = load_err("", &["colour=1"]);
    assert!(e.contains("unknown field `colour`"), "{e}");
    // Indexing past the end, or into a number.
    let e = load_err("", &["objects.2.shape=box"]);
    assert!(e.contains("`objects` has 0 entries"), "{e}");
    let one = "[[objects]]\nshape = \"wall\"\nposition = [0, 0.01]\n";
    let e = load_err(one, &["objects.first.shape=box"]);
    assert!(e.contains("array") && e.contains("`first`"), "{e}");
    // Without objects in the file, a named level is a table, which the schema refuses.
    let e = load_err("", &["objects.first.shape=box"]);
    assert!(
        e.contains("expected a sequence") && e.contains("objects"),
        "{e}"
    );
    let e = load_err("duration = 0.1\n", &["duration.x=1"]);
    assert!(e.contains("`duration` is a float"), "{e}");
    // A value of the wrong type.
    let e = load_err("", &["duration=long"]);
    assert!(e.contains("duration") && e.contains("expected f64"), "{e}");
}

#[test]
fn errors_in_the_file_keep_their_line_under_overrides() {
    let e = load_err("seed = 1\nlenght = 3\n", &["duration=0.1"]);
    assert!(e.contains("line 2") && e.contains("`lenght`"), "{e}");
}

#[test]
fn unknown_spec_lists_the_builtins() {
    let e = load("e7", &[]).unwrap_err();
    assert!(matches!(e, Error::UnknownScenario { .. }));
    let e = e.to_string();
    assert!(
        e.contains("`e7`") && e.contains("e1, e2") && e.contains(".toml"),
        "{e}"
    );
}

#[test]
fn files_load_by_path_and_name_themselves_in_errors() {
    let dir = temp_dir("by-path");
    let good = dir.join("good.toml");
    fs::write(&good, "experiment = \"e2\"\nd = 0.025\n").unwrap();
    let s = load(good.to_str().unwrap(), &[]).unwrap();
    assert_eq!(s.objects, vec![experiment_box(0.025, 0.6)]);

    let bad = dir.join("bad.toml");
    fs::write(&bad, "[whisker]\nlength = \"long\"\n").unwrap();
    let e = load(bad.to_str().unwrap(), &[]).unwrap_err().to_string();
    assert!(e.contains("bad.toml") && e.contains("line 2"), "{e}");
}

#[test]
fn trajectory_is_read_relative_to_the_scenario() {
    let dir = temp_dir("trajectory");
    fs::create_dir_all(dir.join("data")).unwrap();
    fs::write(
        dir.join("data/whisk.csv"),
        "# recorded\nt,angle\n0,0\n0.05,0.2\n0.1,0.1\n",
    )
    .unwrap();
    let path = dir.join("run.toml");
    fs::write(
        &path,
        "[base]\nkind = \"trajectory\"\nfile = \"data/whisk.csv\"\n",
    )
    .unwrap();
    let s = load(path.to_str().unwrap(), &[]).unwrap();
    assert_eq!(
        s.base,
        BaseDrive::Trajectory {
            t: vec![0.0, 0.05, 0.1],
            angle: vec![0.0, 0.2, 0.1]
        }
    );
}

#[test]
fn trajectory_errors_name_file_and_line() {
    let dir = temp_dir("trajectory-errors");
    let cases = [
        (
            "t,angle\n0,0\n0.1,0.2\n0.1,0.3\n",
            "line 4",
            "does not increase",
        ),
        ("t,angle\n0,0\n0.1,abc\n", "line 3", "not a number"),
        ("t,angle\n0,0\n0.1,NaN\n", "line 3", "NaN"),
        ("t,angle\n0,0\n0.1,inf\n", "line 3", "not finite"),
        ("t,angle\n0,0\n0.1\n", "line 3", "values"),
        ("time,angle\n0,0\n", "t,angle", "header"),
        ("t,angle\n", "no rows", "t,angle"),
        ("", "no header", "empty"),
    ];
    for (k, (csv, a, b)) in cases.iter().enumerate() {
        let file = dir.join(format!("w{k}.csv"));
        fs::write(&file, csv).unwrap();
        let e = scenario::read_trajectory(&file).unwrap_err().to_string();
        assert!(
            e.contains(&format!("w{k}.csv")) && e.contains(a) && e.contains(b),
            "{csv:?}: {e}"
        );
    }
    // A missing file, through a scenario.
    let path = dir.join("run.toml");
    fs::write(
        &path,
        "[base]\nkind = \"trajectory\"\nfile = \"none.csv\"\n",
    )
    .unwrap();
    let e = load(path.to_str().unwrap(), &[]).unwrap_err().to_string();
    assert!(e.contains("cannot read") && e.contains("none.csv"), "{e}");
}

#[test]
fn sensor_noise_is_stated_channel_by_channel() {
    // Nothing stated: every channel is left to the estimators.
    let loaded = load_full("e2", &[]).unwrap();
    assert_eq!(loaded.stated_sensor_noise, [None; 5]);
    // A partial table states its channels; the others are 0 in a run but not stated.
    let dir = temp_dir("stated-noise");
    let file = dir.join("rig.toml");
    fs::write(
        &file,
        "experiment = \"e2\"\n[sensor_noise]\ntheta12 = 2e-3\nfx = 0.0\n",
    )
    .unwrap();
    let path = file.to_str().unwrap();
    let loaded = load_full(path, &[]).unwrap();
    assert_eq!(
        loaded.stated_sensor_noise,
        [None, Some(2e-3), None, Some(0.0), None]
    );
    assert_eq!(loaded.scenario.sensor_noise.theta01, 0.0);
    assert_eq!(loaded.scenario.sensor_noise.theta12, 2e-3);
    // An override states a channel too.
    let loaded = load_full("e2", &sets(&["sensor_noise.m0=1e-7"])).unwrap();
    assert_eq!(loaded.stated_sensor_noise[2], Some(1e-7));
    // A negative or non-finite level is refused by name.
    let e = load_err("[sensor_noise]\nm0 = -1e-7\n", &[]);
    assert!(e.contains("sensor_noise.m0"), "{e}");
    let e = load_err("[sensor_noise]\nfy = inf\n", &[]);
    assert!(e.contains("sensor_noise.fy"), "{e}");
}

#[test]
fn absurd_speeds_are_refused_by_name() {
    let e = vibrissa_io::scenario::load_str(
        vibrissa_io::scenario::builtin("e2").unwrap(),
        "e2",
        &sets(&["v=1e9"]),
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("invalid v") && e.contains("at most 1000 m/s"),
        "{e}"
    );
}

#[test]
fn the_experiment_box_must_lie_beyond_the_base() {
    for d in ["0", "-0.01"] {
        let e = load_full("e2", &sets(&[&format!("d={d}")]))
            .unwrap_err()
            .to_string();
        assert!(e.contains("invalid d") && e.contains("> 0 m"), "{e}");
    }
    assert!(load_full("e2", &sets(&["d=0.0005"])).is_ok());
}

#[test]
fn objects_may_cross_the_whisker_s_plane() {
    let s = load_str(
        "[[objects]]\nshape = \"box\"\nwidth = 0.01\nheight = 0.01\nposition = [0.025, -0.006]\n\
         velocity = [0.0, 0.6]\nvertical = { bottom = -0.0035, top = 0.01, velocity = 0.1 }\n",
        "test.toml",
        &[],
    )
    .unwrap();
    let v = s.objects[0].vertical.unwrap();
    assert_eq!((v.bottom, v.top, v.velocity), (-0.0035, 0.01, 0.1));
    assert!(s.objects[0].in_plane(0.0349) && !s.objects[0].in_plane(0.0351));
    // Without a speed it stays where it is; an unknown key or a top below the bottom is named.
    let s = load_str(
        "[[objects]]\nshape = \"circle\"\nradius = 0.001\nposition = [0.02, 0.004]\n\
         vertical = { bottom = -0.01, top = 0.01 }\n",
        "test.toml",
        &[],
    )
    .unwrap();
    assert_eq!(s.objects[0].vertical.unwrap().velocity, 0.0);
    let base = "[[objects]]\nshape = \"circle\"\nradius = 0.001\nposition = [0.02, 0.004]\n";
    let e = load_err(
        &format!("{base}vertical = {{ bottom = 0.0, top = 0.01, speed = 1.0 }}\n"),
        &[],
    );
    assert!(e.contains("speed"), "{e}");
    let e = load_err(
        &format!("{base}vertical = {{ bottom = 0.01, top = 0.0 }}\n"),
        &[],
    );
    assert!(e.contains("objects[0].vertical.top"), "{e}");
    let e = load_err(base, &["objects.0.vertical.bottom=1"]);
    assert!(e.contains("vertical"), "{e}");
}

#[test]
fn an_array_of_whiskers_is_read_and_checked() {
    let base = "[whisker]\npreset = \"w30\"\n";
    let text = format!(
        "{base}[[whiskers]]\nname = \"c1\"\n[[whiskers]]\nname = \"c2\"\nposition = [0.0, 0.004]\n\
         angle = 0.1\nwhisker = {{ length = 0.025 }}\nbase = {{ kind = \"sinusoid\", amplitude = 0.2, \
         frequency = 8.0, phase = 0.5, offset = 0.0 }}\n"
    );
    let (_, loaded) = scenario::open_str(&text, "test.toml", &[]).unwrap();
    let w = &loaded.whiskers;
    assert_eq!(w.len(), 2);
    assert_eq!(
        (w[0].name.as_str(), w[0].position, w[0].angle),
        ("c1", [0.0, 0.0], 0.0)
    );
    assert!(w[0].whisker.is_none() && w[0].base.is_none());
    assert_eq!(w[1].whisker.as_ref().unwrap().length, 0.025);
    assert!(matches!(w[1].base, Some(BaseDrive::Sinusoid { frequency, .. }) if frequency == 8.0));
    // Without [[whiskers]] there is no array.
    assert!(load_full("e2", &[]).unwrap().whiskers.is_empty());
    // Errors name the field.
    for (extra, field) in [
        ("[[whiskers]]\nname = \"c1\"\n[[whiskers]]\nname = \"c1\"\nposition = [0.0, 0.01]\n", "whiskers[1].name"),
        ("[[whiskers]]\nname = \"a b\"\n", "whiskers[0].name"),
        ("[[whiskers]]\nname = \"c1\"\n[[whiskers]]\nname = \"c2\"\nposition = [0.015, -0.01]\nangle = 1.57\n", "whiskers[1]"),
        ("[[whiskers]]\nname = \"c1\"\nreach = 3\n", "reach"),
        ("[[whiskers]]\nposition = [0.0, 0.0]\n", "name"),
    ] {
        let e = match scenario::open_str(&format!("{base}{extra}"), "test.toml", &[]) {
            Ok(_) => panic!("{extra}: loaded"),
            Err(e) => e.to_string(),
        };
        assert!(e.contains(field), "{field}: {e}");
    }
}

#[test]
fn a_set_key_of_an_array_of_tables_keeps_its_index_in_the_parser_s_message() {
    let text = "[[objects]]\nshape = \"circle\"\nradius = 0.002\nposition = [0.02, -0.01]\n\
                velocity = [0.0, 0.5]\n\n[[objects]]\nshape = \"circle\"\nradius = 0.002\n\
                position = [0.01, -0.02]\nvelocity = [0.0, 0.5]\n";
    let e = load_err(text, &["objects.1.radius=abc"]);
    assert!(e.contains("in `objects[1].radius`"), "{e}");
    // Two indices written to the same key: the parser's path is left as it is.
    let e = load_err(text, &["objects.0.radius=abc", "objects.1.radius=def"]);
    assert!(e.contains("in `objects.radius`"), "{e}");
}
