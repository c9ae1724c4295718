//! Estimating from one whisker of an array: the family simulates that whisker at its place.

use vibrissa_infer::experiment::Noise;
use vibrissa_infer::Family;

/// The e2 box struck past two whiskers: `a` at the origin, `b` 2 mm along +y turned by 0.1 rad.
const ARRAY: &str = r#"duration = 0.06
sample_rate = 1000

[whisker]
preset = "w30"

[[whiskers]]
name = "a"

[[whiskers]]
name = "b"
position = [0.0, 0.002]
angle = 0.1

[[objects]]
shape = "box"
width = 0.01
height = 0.01
position = [0.025, -0.012]
velocity = [0.0, 0.8]

[unknowns]
"objects.0.position.0" = { range = [0.02, 0.03], name = "x" }
"#;

#[test]
fn one_whisker_of_an_array_is_simulated_where_it_is_mounted() {
    let family = Family::open_str(ARRAY, "two whiskers", &[]).unwrap();
    let p = [0.022];
    let both = family.simulate_array(&p, &Noise::NONE, 3).unwrap();
    // Whisker b, read alone, is simulated at its own place: its channels are those of the
    // array's run, not those of a whisker at the origin.
    let b = family.for_whisker(Some("b"), false).unwrap();
    let alone = b.simulate(&p, &Noise::NONE, 3).unwrap();
    for c in 0..5 {
        for (x, y) in alone.series[c].iter().zip(&both[1].series[c]) {
            assert!(
                (x - y).abs() <= 1e-12 * (1.0 + y.abs()),
                "channel {c}: {x} vs {y}"
            );
        }
    }
    let peak = |s: &[f64]| s.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let differs = (0..5).any(|c| {
        let a = &both[0].series[c];
        let d: f64 = a
            .iter()
            .zip(&alone.series[c])
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max);
        d > 0.05 * peak(a)
    });
    assert!(differs, "whisker b should read otherwise than whisker a");
    // The filter models one whisker at the origin: b is refused, a is not.
    let err = family.for_whisker(Some("b"), true).unwrap_err().to_string();
    assert!(
        err.contains("particle filter") && err.contains("`b`"),
        "{err}"
    );
    assert!(family.for_whisker(Some("a"), true).is_ok());
    // An array's recording needs the whisker named, among the array's.
    let err = family.for_whisker(None, false).unwrap_err().to_string();
    assert!(err.contains("a, b"), "{err}");
    let err = family
        .for_whisker(Some("c"), false)
        .unwrap_err()
        .to_string();
    assert!(err.contains("`c`"), "{err}");
}

#[test]
fn a_randomised_whisker_of_an_array_reads_alike_alone_and_in_the_array() {
    let family = Family::open_str(ARRAY, "two whiskers", &[])
        .unwrap()
        .randomised_if(true)
        .unwrap();
    let p = [0.024];
    let both = family.simulate_array(&p, &Noise::NONE, 11).unwrap();
    let alone = family
        .for_whisker(Some("b"), false)
        .unwrap()
        .simulate(&p, &Noise::NONE, 11)
        .unwrap();
    assert_eq!(alone.series, both[1].series);
    // And the draw changed it from the nominal whisker's run.
    let plain = Family::open_str(ARRAY, "two whiskers", &[])
        .unwrap()
        .simulate_array(&p, &Noise::NONE, 11)
        .unwrap();
    assert_ne!(plain[1].series, both[1].series);
}
