//! The particle filter against runs of the simulator: recovery, tightening, determinism and
//! bad input.

use vibrissa_infer::experiment::Noise;
use vibrissa_infer::pf::{self, Config, Observations, Pf, Prior};
use vibrissa_infer::{Family, Method, Training, Variant};

/// The noisy variant's sensor noise (5% of the clean e2 ranges), tempered as `pf` does.
const SIGMA: [f64; 5] = [
    2.5 * 6.08e-3,
    2.5 * 1.49e-2,
    2.5 * 2.31e-6,
    2.5 * 1.46e-4,
    2.5 * 1.20e-4,
];

/// A filter of `particles` particles fitted to `family` with sensor noise `noise`.
fn fitted(family: &Family, noise: Noise, particles: usize) -> Pf {
    let mut filter = Pf::new(particles);
    filter
        .fit(&Training {
            family: family.clone(),
            samples: Vec::new(),
            calibration: Vec::new(),
            noise,
        })
        .unwrap();
    filter
}

/// Every other sample of `obs` (the recording at half its rate).
fn every_other(obs: &Observations) -> Observations {
    Observations {
        t: obs.t.iter().step_by(2).copied().collect(),
        values: obs
            .values
            .iter()
            .map(|v| v.iter().step_by(2).copied().collect())
            .collect(),
    }
}

/// The first `n` samples of `obs`.
fn first_samples(mut obs: Observations, n: usize) -> Observations {
    for v in obs.values.iter_mut() {
        v.truncate(n);
    }
    obs.t.truncate(n);
    obs
}

fn run_of(d: f64, v: f64) -> Observations {
    let e2 = Family::builtin("e2").unwrap();
    let s = e2.simulate(&[d, v], &Noise::NONE, 3).unwrap();
    Observations::at_rate(s.series, 1000.0)
}

#[test]
fn recovers_distance_and_speed_and_the_posterior_tightens() {
    let obs = run_of(0.022, 0.9);
    let config = Config::e2(SIGMA, 200, 5);
    let post = pf::run(&config, &obs, &mut |_| {}).unwrap();
    assert_eq!(post.unknowns, ["d", "v"]);
    assert_eq!(post.trace.len(), 151);
    let first = &post.trace[0].estimates;
    let last = post.last();
    assert!((last[0].mean - 0.022).abs() < 1e-3, "d = {}", last[0].mean);
    assert!((last[1].mean - 0.9).abs() < 0.05, "v = {}", last[1].mean);
    // Uniform prior at the start, a posterior many times narrower at the end.
    assert!(first[0].std > 0.004 && first[1].std > 0.3);
    assert!(last[0].std < 0.2 * first[0].std && last[1].std < 0.2 * first[1].std);
    assert!(post.resamples > 0);
    assert!(post
        .trace
        .iter()
        .all(|r| r.ess >= 1.0 && r.ess <= 200.0 + 1e-9));
}

/// A scenario as calibration writes them: the whisker in a compliant follicle, and sensors whose
/// gains are far from 1 (a calibrated angle gain absorbs the recording chain's joint spacing) and
/// whose offsets are not 0. The filter must predict what the sensors record, not the whisker's
/// own channels.
#[test]
fn recovers_distance_on_a_scenario_with_sensor_gains_offsets_and_a_follicle_spring() {
    let sets = [
        "whisker.follicle={ kind = \"spring\", stiffness = 1.4e-4, damping = 4.5e-8 }",
        "sensors.theta01.gain=0.55",
        "sensors.theta01.offset=-1e-3",
        "sensors.theta12.gain=0.45",
        "sensors.theta12.offset=-8e-4",
        "sensors.fx.gain=1.08",
        "sensors.fx.offset=-1.5e-5",
        "sensors.fy.gain=0.93",
        "sensors.fy.offset=8e-6",
    ]
    .map(String::from);
    let family = Family::open("e2", &sets).unwrap();
    // Sensor noise of 3% of each channel's range (the noisy variant's is 5%).
    let noise = Noise {
        sensor: family
            .noise(Variant::Noisy)
            .unwrap()
            .sensor
            .map(|s| 0.6 * s),
        process: 0.0,
    };
    let filter = fitted(&family, noise, 400);
    let strikes = [(0.017, 0.5), (0.021, 1.1), (0.025, 0.8), (0.028, 1.3)];
    let mut inside = 0;
    for (k, (d, v)) in strikes.into_iter().enumerate() {
        let run = family.simulate(&[d, v], &noise, 20 + k as u64).unwrap();
        let e = filter.predict(&run.series).unwrap();
        let [lo, hi] = e[0].ci90;
        let report = format!(
            "d = {d}, v = {v}: estimated d = {} (90%: {lo}…{hi}), v = {}",
            e[0].mean, e[1].mean
        );
        assert!((e[0].mean - d).abs() < 0.6e-3, "{report}");
        assert!((e[1].mean - v).abs() < 0.1, "{report}");
        inside += usize::from(lo <= d && d <= hi);
    }
    // 90% intervals: at least 3 of the 4 hold the truth.
    assert!(inside >= 3, "{inside} of 4 intervals hold d");
}

#[test]
fn same_bits_on_one_and_two_threads() {
    let obs = first_samples(run_of(0.018, 1.2), 30);
    let config = Config::e2(SIGMA, 64, 9);
    let on = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| pf::run(&config, &obs, &mut |_| {}).unwrap())
    };
    assert_eq!(on(1), on(2));
}

/// Islands: the filter split into independent filters is the merge of those filters run alone,
/// its intervals hold every island's mean and its counts add up; too few particles for a second
/// island leave the filter whole.
#[test]
fn islands_are_independent_filters_merged() {
    let obs = first_samples(run_of(0.02, 0.6), 60);
    let mut config = Config::e2(SIGMA, 2000, 3);
    config.islands = 2;
    let parts: Vec<_> = pf::islands::island_configs(&config)
        .iter()
        .map(|c| pf::run(c, &obs, &mut |_| {}).unwrap())
        .collect();
    assert_eq!(parts.len(), 2);
    let merged = pf::run(&config, &obs, &mut |_| {}).unwrap();
    assert_eq!(merged, pf::islands::merge(parts.clone()).unwrap());
    assert_eq!(merged.steps, parts[0].steps + parts[1].steps);
    for (k, row) in merged.trace.iter().enumerate() {
        assert!((row.ess - parts[0].trace[k].ess - parts[1].trace[k].ess).abs() < 1e-9);
        for (u, e) in row.estimates.iter().enumerate() {
            for p in &parts {
                let m = p.trace[k].estimates[u].mean;
                assert!(
                    e.ci90[0] <= m && m <= e.ci90[1],
                    "sample {k}: {e:?} and {m}"
                );
            }
        }
    }
    assert_ne!(
        parts[0].last()[0],
        parts[1].last()[0],
        "the islands draw their own streams"
    );
    // 1999 particles: one island of them all, the filter itself.
    config.particles = 1999;
    let whole = Config {
        islands: 1,
        ..config.clone()
    };
    assert_eq!(
        pf::run(&config, &obs, &mut |_| {}).unwrap(),
        pf::run(&whole, &obs, &mut |_| {}).unwrap()
    );
}

#[test]
fn islands_fed_one_sample_at_a_time_give_the_same_bits_as_on_a_whole_recording() {
    let obs = first_samples(run_of(0.024, 0.9), 50);
    let mut config = Config::e2(SIGMA, 2000, 4);
    config.islands = 2;
    let whole = pf::run(&config, &obs, &mut |_| {}).unwrap();
    let mut online = pf::islands::Islands::new(&config, 1e-3).unwrap();
    assert_eq!(online.count(), 2);
    for (k, &t) in obs.t.iter().enumerate() {
        let y: [f64; 5] = std::array::from_fn(|c| obs.values[c][k]);
        if k == 10 {
            // A sample off the period's grid is refused by every island, and none moves.
            assert!(online.update(t + 0.4e-3, &y).is_err());
            assert_eq!(online.posterior().trace.len(), 10);
        }
        let row = online.update(t, &y).unwrap().clone();
        assert_eq!(&row, &whole.trace[k], "sample {k}");
        assert_eq!(online.particles().len(), 2);
    }
    assert_eq!(online.posterior().steps, whole.steps);
    assert_eq!(online.finish().unwrap(), whole);
}

#[test]
fn fed_one_sample_at_a_time_the_filter_gives_the_same_bits_as_on_a_whole_recording() {
    let obs = first_samples(run_of(0.024, 0.9), 60);
    let config = Config::e2(SIGMA, 200, 4);
    let whole = pf::run(&config, &obs, &mut |_| {}).unwrap();
    let mut online = pf::Filter::new(&config, 1e-3).unwrap();
    for (k, &t) in obs.t.iter().enumerate() {
        let y: [f64; 5] = std::array::from_fn(|c| obs.values[c][k]);
        let row = online.update(t, &y).unwrap().clone();
        assert_eq!(&row, &whole.trace[k], "sample {k}");
        // The cloud, read after every sample, is the one the posterior summarises.
        let cloud = online.particles();
        assert_eq!(cloud.unknowns, ["d", "v"]);
        assert_eq!(cloud.weights.len(), 200);
        assert!((cloud.weights.iter().sum::<f64>() - 1.0).abs() < 1e-9);
        for (u, values) in cloud.values.iter().enumerate() {
            let mean: f64 = values.iter().zip(&cloud.weights).map(|(x, w)| x * w).sum();
            let reported = row.estimates[u].mean;
            assert!(
                (mean - reported).abs() <= 1e-9 * reported.abs().max(1.0),
                "sample {k}, {}: {mean} vs {reported}",
                cloud.unknowns[u]
            );
        }
        if k == 30 {
            // A sample out of step is refused and leaves the filter as it was.
            let e = online.update(t + 0.5e-3, &y).unwrap_err().to_string();
            assert!(e.contains("irregular sample times"), "{e}");
        }
    }
    assert_eq!(online.finish(), whole);
    assert!(pf::Filter::new(&config, 0.0).is_err());
}

#[test]
fn unknown_start_is_estimated() {
    let e2 = Family::builtin("e2").unwrap();
    let s = e2
        .simulate_delayed(&[0.025, 0.6], 0.02, &Noise::NONE, 4)
        .unwrap();
    assert_eq!(s.series[0].len(), 171);
    let obs = Observations::at_rate(s.series, 1000.0);
    let mut config = Config::e2(SIGMA, 300, 6);
    config.priors[2] = Prior::uniform(0.0, 0.05);
    let post = pf::run(&config, &obs, &mut |_| {}).unwrap();
    assert_eq!(post.unknowns, ["d", "v", "t0"]);
    let last = post.last();
    assert!(
        (last[2].mean - 0.02).abs() < 0.004,
        "t0 = {} (d {}, v {})",
        last[2].mean,
        last[0].mean,
        last[1].mean
    );
    assert!(
        (last[0].mean - 0.025).abs() < 1.5e-3,
        "d = {}",
        last[0].mean
    );
}

#[test]
fn missing_values_are_skipped_and_gaps_predicted_across() {
    let mut obs = first_samples(run_of(0.02, 0.6), 40);
    obs.values[1][10] = f64::NAN;
    obs.values[3][11] = f64::NAN;
    // Samples 20..25 missing altogether: a gap of six periods.
    for v in obs.values.iter_mut() {
        v.drain(20..25);
    }
    obs.t.drain(20..25);
    let post = pf::run(&Config::e2(SIGMA, 32, 1), &obs, &mut |_| {}).unwrap();
    assert_eq!(post.skipped, 2);
    assert_eq!(post.trace.len(), 35);
    assert!((post.trace[20].t - 0.025).abs() < 1e-12);
}

#[test]
fn bad_input_is_refused_with_the_field_named() {
    let obs = run_of(0.02, 0.6);
    let err = |config: &Config, obs: &Observations| {
        pf::run(config, obs, &mut |_| {}).unwrap_err().to_string()
    };
    let mut c = Config::e2(SIGMA, 0, 1);
    assert!(err(&c, &obs).contains("particles"));
    c.particles = 8;
    c.channels = vec![7];
    assert!(err(&c, &obs).contains("channels"));
    c.channels = vec![0, 1];
    c.sigma[1] = f64::NAN;
    assert!(err(&c, &obs).contains("theta12"));
    let c = Config::e2(SIGMA, 8, 1);
    let mut irregular = obs.clone();
    irregular.t[5] += 3e-4;
    assert!(err(&c, &irregular).contains("irregular"));
    let mut short = obs.clone();
    short.values[4].truncate(10);
    assert!(err(&c, &short).contains("fy"));
}

/// A whisker the filter is not told: softer than the scenario says, its angles recorded by a
/// chain of other joint spacing (`theta12` at 0.45 of the scenario's, `theta01` at 0.7), its
/// wrench sensors a few percent off. Told the nominal scenario, the filter collapses onto wrong
/// distances; on the randomised family it entertains other whiskers and carries the sensors'
/// gains as unknowns, and its intervals hold the truth.
#[test]
fn on_a_randomised_family_the_filter_learns_the_sensors_and_stays_honest() {
    let sets = [
        "whisker.youngs_modulus=2.9e9",
        "sensors.theta01.gain=0.7",
        "sensors.theta12.gain=0.45",
        "sensors.m0.gain=1.03",
        "sensors.fx.gain=0.97",
        "sensors.fy.gain=1.02",
    ]
    .map(String::from);
    let truth = Family::open("e2", &sets).unwrap();
    let nominal = Family::builtin("e2").unwrap();
    let noise = Noise {
        sensor: truth.noise(Variant::Noisy).unwrap().sensor.map(|s| 0.6 * s),
        process: 0.0,
    };
    let told = fitted(&nominal, noise, 4000);
    let rough = fitted(&nominal.clone().randomised_if(true).unwrap(), noise, 4000);
    let strikes = [(0.017, 0.5), (0.021, 1.1), (0.025, 0.8), (0.028, 1.3)];
    let (mut told_inside, mut rough_inside) = (0, 0);
    let mut d_errors = Vec::new();
    for (k, (d, v)) in strikes.into_iter().enumerate() {
        let run = truth.simulate(&[d, v], &noise, 40 + k as u64).unwrap();
        let e = told.predict(&run.series).unwrap();
        told_inside += usize::from(e[0].ci90[0] <= d && d <= e[0].ci90[1]);
        let post = rough.posterior(&run.series).unwrap();
        let e = post.last();
        let report = format!("d = {d}, v = {v}: {:?}", e);
        d_errors.push((e[0].mean - d).abs());
        assert!((e[0].mean - d).abs() < 3e-3, "{report}");
        assert!((e[1].mean - v).abs() < 0.1, "{report}");
        rough_inside += usize::from(e[0].ci90[0] <= d && d <= e[0].ci90[1]);
        // The angle gains are learned, to under a third of their prior's spread (0.5; the
        // wrench's stay near 1 within their prior).
        let sensors = post.sensors.as_ref().expect("a sensor posterior");
        let g12 = sensors.gain[1];
        assert!((g12.mean - 0.45).abs() < 0.1, "theta12 gain {g12:?}");
        assert!(g12.std > 0.0 && g12.std < 0.15, "theta12 gain {g12:?}");
    }
    // The distance to about a millimetre on the whole (on stand-in whiskers the filter's mean
    // error is 0.8-1.4 mm), one strike at most 3 mm off.
    let mean = d_errors.iter().sum::<f64>() / d_errors.len() as f64;
    assert!(mean < 2e-3, "mean d error {mean}: {d_errors:?}");
    assert!(
        told_inside <= 1,
        "told the nominal: {told_inside} of 4 intervals hold d"
    );
    assert!(
        rough_inside >= 3,
        "randomised: {rough_inside} of 4 intervals hold d"
    );
}

#[test]
fn a_recording_below_a_kilohertz_is_filtered() {
    // The strike of the first test, every other sample: 500 Hz, whose period is longer than the
    // longest step the physics takes (the ringing model then steps twice per period).
    let full = run_of(0.022, 0.9);
    let obs = every_other(&full);
    assert_eq!(obs.t.len(), 76);
    let config = Config::e2(SIGMA, 200, 5);
    let post = pf::run(&config, &obs, &mut |_| {}).unwrap();
    assert_eq!(post.trace.len(), 76);
    let last = post.last();
    assert!(
        (last[0].mean - 0.022).abs() < 1.5e-3,
        "d = {}",
        last[0].mean
    );
    assert!((last[1].mean - 0.9).abs() < 0.1, "v = {}", last[1].mean);
    // Some particles' boxes left for good, and their whiskers rang on the free model.
    assert!(post.ringing_share > 0.0, "{}", post.ringing_share);
}

#[test]
fn a_faster_recording_says_what_its_decimation_says() {
    // One strike recorded at 2 kHz and the same recording at 1 kHz (every other sample): the
    // filter weighs evidence per millisecond, so the faster recording's posterior is no narrower
    // than the slower one's (counting every sample as at 1 kHz made the distance's √2 narrower:
    // 0.32 against 0.45 mm).
    let e2 = Family::builtin("e2")
        .unwrap()
        .with_timing(2000.0, 301)
        .unwrap();
    let s = e2.simulate(&[0.024, 0.6], &Noise::NONE, 7).unwrap();
    let fast = Observations::at_rate(s.series, 2000.0);
    let slow = every_other(&fast);
    let config = Config::e2(SIGMA, 400, 5);
    let post_fast = pf::run(&config, &fast, &mut |_| {}).unwrap();
    let post_slow = pf::run(&config, &slow, &mut |_| {}).unwrap();
    assert!((post_fast.rate_widening - 2f64.sqrt()).abs() < 1e-12);
    assert_eq!(post_slow.rate_widening, 1.0);
    for (u, (f, s)) in post_fast.last().iter().zip(post_slow.last()).enumerate() {
        let ratio = f.std / s.std;
        assert!(
            ratio > 0.8 && ratio < 1.6,
            "unknown {u}: std {} vs {}",
            f.std,
            s.std
        );
        assert!(
            (f.mean - s.mean).abs() < 1.645 * s.std,
            "unknown {u}: {} vs {} ± {}",
            f.mean,
            s.mean,
            s.std
        );
    }
}

/// The default prior of whiskers around `e2`'s.
fn randomised_e2() -> Family {
    Family::builtin("e2")
        .unwrap()
        .randomised(vibrissa_infer::randomise::Randomisation::default())
        .unwrap()
}

/// Sensor noise of the randomised filters' tests.
const LEVEL: [f64; 5] = [2e-3, 5e-3, 8e-7, 5e-5, 4e-5];

/// A clean strike of `family` at d = 22 mm, v = 0.8 m/s (seed 3), read for the filter.
fn clean_strike(family: &Family, channels: &[usize]) -> vibrissa_infer::Recording {
    let s = family.simulate(&[0.022, 0.8], &Noise::NONE, 3).unwrap();
    let t: Vec<f64> = (0..s.series[0].len()).map(|k| k as f64 * 1e-3).collect();
    vibrissa_infer::Recording::from_columns(
        "strike",
        t,
        s.series.into_iter().map(Some).collect(),
        None,
        channels,
        vibrissa_infer::Reader::Filter,
    )
    .unwrap()
}

#[test]
fn a_randomised_filter_widens_its_intervals_to_hold_on_held_out_whiskers() {
    use vibrissa_infer::pf::recording::{estimate, fitted, Options};
    let family = randomised_e2();
    let level = LEVEL;
    let mut options = Options::new(100);
    options.alternatives = 7;
    options.interval_runs = 6;
    let widened = fitted(&family, &level, &options).unwrap();
    let names: Vec<&str> = widened
        .interval_scale
        .iter()
        .map(|(k, _)| k.as_str())
        .collect();
    assert_eq!(names, ["d", "v"]);
    assert!(widened.interval_scale.iter().all(|(_, f)| *f >= 1.0));
    // The same filter without the held-out runs: the estimate is the same, its spread narrower
    // by the factors, where the widened one stays within the prior's (its interval too).
    options.interval_runs = 0;
    let plain = fitted(&family, &level, &options).unwrap();
    assert!(plain.interval_scale.is_empty());
    let rec = clean_strike(&family, &options.channels);
    let (a, b) = (
        estimate(&widened, &family, &rec, &options).unwrap(),
        estimate(&plain, &family, &rec, &options).unwrap(),
    );
    let support = a.config.support(&a.posterior.unknowns);
    for (u, (_, f)) in widened.interval_scale.iter().enumerate() {
        let (w, p) = (a.posterior.last()[u], b.posterior.last()[u]);
        let [lo, hi] = support[u].expect("a prior");
        let expected = (f * p.std).min((hi - lo) / 12f64.sqrt());
        assert_eq!(w.mean, p.mean);
        assert!(
            (w.std - expected).abs() <= 1e-12 * w.std.max(1e-300),
            "{w:?} {p:?}"
        );
        assert!(
            lo <= w.ci90[0] && w.ci90[1] <= hi,
            "{w:?} within [{lo}, {hi}]"
        );
    }
    // A nominal family's filter is not widened.
    let nominal = fitted(&Family::builtin("e2").unwrap(), &level, &Options::new(50)).unwrap();
    assert!(nominal.interval_scale.is_empty());
}

#[test]
fn a_randomised_filter_reports_its_belief_over_the_whiskers() {
    use vibrissa_core::whisker::{Damping, Follicle};
    use vibrissa_infer::pf::recording::{estimate, fitted, Options};
    let family = randomised_e2();
    let level = LEVEL;
    let mut options = Options::new(800);
    options.alternatives = 7;
    options.interval_runs = 0;
    let filter = fitted(&family, &level, &options).unwrap();
    let config = filter.config(&family, filter.sigma().unwrap()).unwrap();
    let whiskers: Vec<_> = std::iter::once(&config.whisker)
        .chain(&config.alternatives)
        .collect();
    // The recording's whisker: the clamped alternative whose modulus is farthest from the
    // scenario's (the other parameters it differs in go into the scenario too).
    let e0 = config.whisker.youngs_modulus;
    let truth = config
        .alternatives
        .iter()
        .filter(|w| w.follicle == Follicle::Clamped)
        .max_by(|a, b| {
            let far =
                |w: &&vibrissa_core::whisker::WhiskerParams| (w.youngs_modulus / e0).ln().abs();
            far(a).total_cmp(&far(b))
        })
        .expect("a clamped alternative");
    let Damping::ModalRatio { ratio } = truth.damping else {
        panic!("the prior keeps the damping's kind");
    };
    let text = format!(
        "experiment = \"e2\"\n[whisker]\npreset = \"w30\"\nyoungs_modulus = {}\ndensity = {}\n\
         tip_radius = {}\n[whisker.damping]\nkind = \"modal_ratio\"\nratio = {ratio}\n",
        truth.youngs_modulus, truth.density, truth.tip_radius
    );
    let recorded = Family::open_str(&text, "test", &[]).unwrap();
    let rec = clean_strike(&recorded, &options.channels);
    let est = estimate(&filter, &family, &rec, &options).unwrap();
    let named = est.named();
    let get = |key: &str| {
        named
            .iter()
            .find(|(k, _)| k == key)
            .unwrap_or_else(|| panic!("{key} missing from {named:?}"))
            .1
    };
    // Every whisker parameter the prior varies is reported, finite, within the whiskers' range.
    for key in [
        "whisker.youngs_modulus",
        "whisker.density",
        "whisker.damping.ratio",
    ] {
        let e = get(key);
        assert!(
            e.mean.is_finite() && e.std.is_finite() && e.ci90[0] <= e.ci90[1],
            "{key}: {e:?}"
        );
    }
    let c = get("whisker.follicle.compliance");
    assert!(c.ci90[0] >= 0.0 && c.mean.is_finite(), "{c:?}");
    // The belief over the modulus moved from the prior's (equal weights on the eight whiskers)
    // towards the recording's, and its interval holds it.
    let prior_mean = whiskers.iter().map(|w| w.youngs_modulus).sum::<f64>() / whiskers.len() as f64;
    let e = get("whisker.youngs_modulus");
    assert!(
        (e.mean - truth.youngs_modulus).abs() < 0.5 * (prior_mean - truth.youngs_modulus).abs(),
        "posterior {e:?}, prior mean {prior_mean}, truth {}",
        truth.youngs_modulus
    );
    assert!(
        e.covers(truth.youngs_modulus),
        "{e:?} vs {}",
        truth.youngs_modulus
    );
    // A filter told its whisker reports none.
    let nominal = Family::builtin("e2").unwrap();
    let told = fitted(&nominal, &level, &Options::new(100)).unwrap();
    let est = estimate(&told, &nominal, &rec, &Options::new(100)).unwrap();
    assert!(est.named().iter().all(|(k, _)| !k.starts_with("whisker.")));
}

#[test]
fn particles_stepped_in_lane_groups_reach_the_bits_they_reach_alone() {
    // A whole noisy strike (approach, contact, release, ringing), with the known whisker and
    // with alternative whiskers and unknown sensors (particles of several whiskers, moved boxes).
    let family = randomised_e2();
    let s = family
        .simulate(
            &[0.021, 0.9],
            &Noise {
                sensor: LEVEL,
                process: 0.0,
            },
            5,
        )
        .unwrap();
    let obs = Observations::at_rate(s.series, 1000.0);
    let known = Config::e2(SIGMA, 256, 4);
    let mut alternatives = known.clone();
    alternatives.alternatives = (0..3)
        .map(|k| {
            let mut w = known.whisker.clone();
            w.youngs_modulus *= 1.0 + 0.08 * (k as f64 - 1.0);
            w
        })
        .collect();
    alternatives.sensor_spread = pf::SensorSpread::rough();
    for config in [known, alternatives] {
        let grouped = pf::run(&config, &obs, &mut |_| {}).unwrap();
        let alone = pf::run(
            &Config {
                lane_groups: false,
                coarse_rule: Default::default(),
                ..config.clone()
            },
            &obs,
            &mut |_| {},
        )
        .unwrap();
        assert!(grouped.ringing_share > 0.2, "{}", grouped.ringing_share);
        assert_eq!(grouped, alone);
    }
}
