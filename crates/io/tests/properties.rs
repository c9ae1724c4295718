//! Property tests of the readers: no input, however malformed, panics a reader, and what a
//! reader accepts is what was written.
//!
//! Each property runs on a few hundred generated inputs (proptest's default of 256 cases, more
//! where an input is cheap); a failing case is shrunk to a minimal one and printed.

use proptest::prelude::*;
use proptest::test_runner::RngSeed;
use vibrissa_io::scenario::{builtin, load_str};
use vibrissa_io::series::{read_csv_str, to_csv_string, Series};

/// Largest penetration of the whisker into the box at the end of a step, m. The contact solve
/// leaves some: on these strikes up to a few micrometres (2.7 µm for a 42 mm whisker struck at
/// 1.1 m/s), a few per cent of the whisker's radius.
const PENETRATION: f64 = 5e-6;

/// The built-in `e2` scenario's text: the valid document that mutations start from.
fn e2_text() -> &'static str {
    builtin("e2").expect("e2 is built in")
}

/// Replaces the byte range `at..at + len` of `text` (clamped, on character boundaries) by
/// `with`.
fn splice(text: &str, at: usize, len: usize, with: &str) -> String {
    let mut start = at.min(text.len());
    while !text.is_char_boundary(start) {
        start -= 1;
    }
    let mut end = (start + len).min(text.len());
    while !text.is_char_boundary(end) {
        end += 1;
    }
    format!("{}{}{}", &text[..start], with, &text[end..])
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, rng_seed: RngSeed::Fixed(0x5eed), ..ProptestConfig::default() })]

    /// Arbitrary text read as a CSV time series: an error or a series, never a panic; an error
    /// names the origin.
    #[test]
    fn csv_reader_never_panics_on_any_text(text in "\\PC{0,400}") {
        if let Err(e) = read_csv_str(&text, "fuzz.csv") {
            prop_assert!(e.to_string().starts_with("fuzz.csv"), "{e}");
        }
    }

    /// Text made of the characters a CSV holds (digits, signs, separators, newlines, column
    /// names): the reader's edges are reached far more often than with arbitrary text.
    #[test]
    fn csv_reader_never_panics_on_csv_like_text(
        text in "(t|theta01|theta12|m0|fx|fy|nan|inf|-|\\+|e|E|\\.|,|;|#|\"| |[0-9]|\n){0,300}"
    ) {
        let _ = read_csv_str(&text, "fuzz.csv");
    }

    /// A series of finite numbers written as CSV reads back with the same columns and values.
    #[test]
    fn csv_round_trips_finite_values(
        rows in prop::collection::vec(prop::collection::vec(-1e6f64..1e6, 3), 1..40)
    ) {
        let mut s = Series::new(&["t", "theta01", "theta12"]);
        for (k, r) in rows.iter().enumerate() {
            s.push_row(&[k as f64 * 1e-3, r[1], r[2]]);
        }
        let text = to_csv_string(&s).expect("writes");
        let back = read_csv_str(&text, "round.csv").expect("reads back");
        prop_assert_eq!(back.rows(), rows.len());
        for name in ["t", "theta01", "theta12"] {
            let (a, b) = (s.column(name).unwrap(), back.column(name).unwrap());
            for (x, y) in a.iter().zip(b) {
                prop_assert!((x - y).abs() <= 1e-12 * x.abs().max(1.0), "{name}: {x} vs {y}");
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, rng_seed: RngSeed::Fixed(0x5eed), ..ProptestConfig::default() })]

    /// Arbitrary text read as a scenario file: an error that names the origin, never a panic.
    #[test]
    fn scenario_reader_never_panics_on_any_text(text in "\\PC{0,300}") {
        if let Err(e) = load_str(&text, "fuzz.toml", &[]) {
            prop_assert!(!e.to_string().is_empty());
        }
    }

    /// The built-in `e2` with a stretch of its text replaced by arbitrary text: the reader
    /// accepts it (the result is a checked scenario) or refuses it, never panics.
    #[test]
    fn scenario_reader_never_panics_on_mutated_e2(
        at in 0usize..2000,
        len in 0usize..40,
        with in "(=|\\[|\\]|\\.|-|[0-9]|e|nan|inf|true|\"|d|v|whisker|segments|dt| |\n){0,20}"
    ) {
        let text = splice(e2_text(), at, len, &with);
        if let Ok(s) = load_str(&text, "mutated.toml", &[]) {
            prop_assert!(s.check().is_ok(), "an accepted scenario must be valid");
        }
    }

    /// `--set` overrides with arbitrary keys and values on `e2`: a scenario or an error that
    /// names the override's key, never a panic.
    #[test]
    fn overrides_never_panic(
        key in "(d|v|dt|segments|duration|sample_rate|whisker\\.length|whisker\\.youngs_modulus|whisker\\.follicle\\.kind|sensor_noise\\.fx|nonsense)",
        value in "(-?[0-9]{1,4}(\\.[0-9]{1,3})?(e-?[0-9]{1,2})?|nan|inf|-inf|spring|clamped|\"x\"|)"
    ) {
        let set = format!("{key}={value}");
        let _ = load_str(e2_text(), "e2", &[set]);
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, rng_seed: RngSeed::Fixed(0x5eed), ..ProptestConfig::default() })]

    /// Admissible whiskers (modulus, density, length, radii, a follicle spring, damping) struck
    /// by the `e2` box at any admissible distance and speed: the run finishes with every recorded
    /// number finite.
    #[test]
    fn admissible_strikes_simulate_to_finite_series(
        e in 0.5e9f64..8e9,
        rho in 500f64..2000.0,
        length in 0.015f64..0.06,
        tip in 0.3f64..1.0,
        follicle in prop::option::of(1e-5f64..1e-2),
        ratio in 0.001f64..0.3,
        d in 0.010f64..0.035,
        v in 0.05f64..3.0,
    ) {
        let mut sets = vec![
            format!("whisker.youngs_modulus={e}"),
            format!("whisker.density={rho}"),
            format!("whisker.length={length}"),
            format!("whisker.tip_radius={}", 1e-4 * tip),
            "whisker.damping.kind=modal_ratio".to_string(),
            format!("whisker.damping.ratio={ratio}"),
            format!("d={d}"),
            format!("v={v}"),
            "duration=0.03".to_string(),
        ];
        if let Some(k) = follicle {
            sets.push("whisker.follicle.kind=spring".into());
            sets.push(format!("whisker.follicle.stiffness={k}"));
            sets.push(format!("whisker.follicle.damping={}", k * 1e-4));
        }
        // Every draw is admissible: the file must load and the run must finish.
        let s = load_str(e2_text(), "e2", &sets);
        prop_assert!(s.is_ok(), "{sets:?}: {}", s.unwrap_err());
        let out = vibrissa_core::sim::run(&s.unwrap(), &mut |_| {});
        prop_assert!(out.is_ok(), "{sets:?}: {}", out.unwrap_err());
        let out = out.unwrap();
        prop_assert!(out.rows.len() > 10);
        // The whisker never ends a step inside the box by more than a few micrometres.
        prop_assert!(out.max_penetration < PENETRATION, "penetration {} m for {sets:?}", out.max_penetration);
        // t and the five channels (the contact columns are NaN while nothing touches).
        for row in &out.rows {
            prop_assert!(row[..6].iter().all(|x| x.is_finite()), "{row:?} for {sets:?}");
        }
    }
}
