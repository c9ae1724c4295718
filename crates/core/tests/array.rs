//! Whisker arrays: each whisker runs in its own frame against the same objects.

use vibrissa_core::array::{self, Mount};
use vibrissa_core::objects::Motion;
use vibrissa_core::scenes;
use vibrissa_core::sim::{self, Scenario};

fn mount(name: &str, position: [f64; 2], angle: f64) -> Mount {
    Mount {
        name: name.into(),
        position,
        angle,
        whisker: None,
        base: None,
        sensors: None,
    }
}

fn e2(d: f64, v: f64) -> Scenario {
    Scenario {
        objects: vec![scenes::e2_box(d, v)],
        ..Scenario::default()
    }
}

#[test]
fn a_whisker_at_the_origin_is_the_single_whisker_run() {
    let sc = e2(0.02, 0.6);
    let single = sim::run(&sc, &mut |_| {}).unwrap();
    let runs = array::run(&sc, &[mount("c1", [0.0, 0.0], 0.0)]).unwrap();
    assert_eq!(runs.len(), 1);
    let same = single
        .rows
        .iter()
        .flatten()
        .zip(runs[0].rows.iter().flatten())
        .all(|(a, b)| a.to_bits() == b.to_bits());
    assert!(same);
}

#[test]
fn a_moved_and_turned_whisker_sees_the_moved_and_turned_strike() {
    // The e2 strike carried into a frame turned by 0.7 rad and moved to (5, -3) mm: a whisker
    // mounted there records what the unmoved whisker records of the unmoved box.
    let (p, phi) = ([0.005, -0.003], 0.7f64);
    let (s, c) = phi.sin_cos();
    let turn = |v: [f64; 2]| [c * v[0] - s * v[1], s * v[0] + c * v[1]];
    let mut moved = scenes::e2_box(0.02, 0.6);
    let local = moved.position;
    let q = turn(local);
    moved.position = [p[0] + q[0], p[1] + q[1]];
    moved.angle += phi;
    if let Motion::Constant { velocity, .. } = &mut moved.motion {
        *velocity = turn(*velocity);
    }
    let scene = Scenario {
        objects: vec![moved],
        ..Scenario::default()
    };
    // A second whisker far away, pointing the other way, never touched.
    let runs = array::run(
        &scene,
        &[
            mount("near", p, phi),
            mount("far", [-0.05, 0.0], std::f64::consts::PI),
        ],
    )
    .unwrap();
    let reference = sim::run(&e2(0.02, 0.6), &mut |_| {}).unwrap();
    let range = |k: usize| {
        let v = reference
            .rows
            .iter()
            .map(|r| r[k])
            .filter(|x| x.is_finite());
        let (lo, hi) = v.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
            (a.min(x), b.max(x))
        });
        hi - lo
    };
    for k in 1..10 {
        let worst = reference
            .rows
            .iter()
            .zip(&runs[0].rows)
            .map(|(a, b)| {
                if a[k].is_nan() && b[k].is_nan() {
                    0.0
                } else {
                    (a[k] - b[k]).abs()
                }
            })
            .fold(0.0, f64::max);
        assert!(worst <= 1e-6 * range(k).max(1e-12), "column {k}: {worst}");
    }
    assert!(runs[1].rows.iter().all(|r| r[6] == 0.0 && r[1] == 0.0));
}

#[test]
fn bad_arrays_are_refused_by_field() {
    let sc = e2(0.02, 0.6);
    let cases: Vec<(Vec<Mount>, &str)> = vec![
        (vec![], "whiskers"),
        (vec![mount("c.1", [0.0, 0.0], 0.0)], "whiskers[0].name"),
        (
            vec![mount("c1", [0.0, 0.0], 0.0), mount("c1", [0.0, 0.01], 0.0)],
            "whiskers[1].name",
        ),
        (
            vec![mount("c1", [0.0, 0.0], 0.0), mount("c2", [0.0, 0.0], 0.3)],
            "whiskers[1]",
        ),
        (
            // Crossing: c2 starts below c1's middle and points up through it.
            vec![
                mount("c1", [0.0, 0.0], 0.0),
                mount("c2", [0.015, -0.01], 1.57),
            ],
            "whiskers[1]",
        ),
        (
            vec![mount("c1", [f64::NAN, 0.0], 0.0)],
            "whiskers[0].position[0]",
        ),
    ];
    for (mounts, field) in cases {
        let e = array::run(&sc, &mounts).unwrap_err().to_string();
        assert!(e.contains(field), "{field}: {e}");
    }
    // Parallel whiskers 3 mm apart are fine.
    array::run(
        &sc,
        &[mount("c1", [0.0, 0.0], 0.0), mount("c2", [0.0, 0.003], 0.0)],
    )
    .unwrap();
}

#[test]
fn each_whisker_is_read_through_its_own_sensors() {
    use vibrissa_core::sim::{Response, SensorResponse};
    let sc = e2(0.02, 0.6);
    let plain = [mount("c1", [0.0, 0.0], 0.0), mount("c2", [0.0, 0.003], 0.0)];
    let mut own = plain.clone();
    own[1].sensors = Some(SensorResponse {
        theta01: Response {
            gain: 2.0,
            offset: 0.0,
        },
        m0: Response {
            gain: 1.0,
            offset: 1e-6,
        },
        ..SensorResponse::default()
    });
    let before = array::run(&sc, &plain).unwrap();
    let after = array::run(&sc, &own).unwrap();
    // The first whisker, read by the scenario's sensors, records what it did (bit for bit; the
    // contact columns hold NaN out of contact).
    let bits =
        |rows: &[[f64; 10]]| -> Vec<u64> { rows.iter().flatten().map(|x| x.to_bits()).collect() };
    assert!(bits(&before[0].rows) == bits(&after[0].rows));
    // The second records its theta01 doubled and its m0 raised by the offset; nothing else moves.
    let (theta01, theta12, m0) = (1, 2, 3);
    let mut touched = false;
    for (b, a) in before[1].rows.iter().zip(&after[1].rows) {
        assert_eq!(a[theta01], 2.0 * b[theta01]);
        assert_eq!(a[m0], b[m0] + 1e-6);
        assert_eq!(a[theta12], b[theta12]);
        touched |= b[theta01] != 0.0;
    }
    assert!(touched, "the box never bent the second whisker");
    // A gain of 0 is refused, naming the whisker's field.
    own[0].sensors = Some(SensorResponse {
        fy: Response {
            gain: 0.0,
            offset: 0.0,
        },
        ..SensorResponse::default()
    });
    let e = array::run(&sc, &own).unwrap_err().to_string();
    assert!(e.contains("whiskers[0].sensors.fy.gain"), "{e}");
}
