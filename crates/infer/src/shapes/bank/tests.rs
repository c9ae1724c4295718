//! Tests of the bank: synthetic pulse-shaped runs stand in for a family's simulations.

use super::fit::{least_loss, temperatures};
use super::*;
use vibrissa_core::rng::Rng;

#[test]
fn the_even_share_is_never_below_the_least_allowed_and_the_misfit_ratio_is_at_least_one() {
    // Two classes, three temperatures' worth of evidence: nine runs named right with
    // confidence and one named wrong with confidence.
    let right = vec![vec![0.0, -20.0]; temperatures().count()];
    let wrong = vec![vec![-20.0, 0.0]; temperatures().count()];
    let mut evidence = vec![right; 9];
    evidence.push(wrong);
    let truth = vec![0; 10];
    let free = least_loss(2, &evidence, &truth, 0.0);
    assert!(free.3 > 0.0 && free.3 < 0.4, "{free:?}");
    let held = least_loss(2, &evidence, &truth, 0.4);
    assert!(held.3 >= 0.4, "{held:?}");
    assert!(held.0 > free.0);
    // The median of the finite values; ratios below 1 or undefined count as 1.
    assert_eq!(median(&[3.0, f64::INFINITY, 1.0, 2.0]), 2.0);
    assert_eq!(median(&[4.0, 1.0, 2.0, 3.0]), 2.5);
    assert!(median(&[f64::NAN]).is_nan());
    assert_eq!(misfit_ratio(50.0, 10.0), 5.0);
    assert_eq!(misfit_ratio(5.0, 10.0), 1.0);
    assert_eq!(misfit_ratio(5.0, f64::NAN), 1.0);
    assert_eq!(misfit_ratio(f64::INFINITY, 10.0), 1.0);
    assert_eq!(nearest(&[3.0, 2.0], &[f64::INFINITY, 1.5]), 1.5);
}

#[test]
fn the_search_starts_from_the_nearest_run_and_then_from_runs_of_other_poses() {
    // Class 1's runs: two near the recording at almost the same pose, one farther at
    // another pose, one at a third pose that cannot be scored; class 0's run is nearest.
    let ranges = [[0.0, 1.0], [5.0, 5.0]];
    let params = vec![
        vec![0.5, 5.0],
        vec![0.20, 5.0],
        vec![0.21, 5.0],
        vec![0.60, 5.0],
        vec![0.90, 5.0],
    ];
    let class_of = [0, 1, 1, 1, 1];
    let d2 = [0.1, 1.0, 1.1, 2.0, f64::INFINITY];
    // The second run lies within the separation of the first (the fixed unknown adds
    // nothing); the run that cannot be scored is never a start, though a third is wanted.
    assert_eq!(
        starts(&params, &class_of, &ranges, 1, &d2, Some(1)),
        vec![1, 3]
    );
    // Scored, it is the third start; a fourth pose apart from all is not taken.
    let mut more = params.clone();
    more.push(vec![0.40, 5.0]);
    let d2_more = [0.1, 1.0, 1.1, 2.0, 3.0, 4.0];
    let class_more = [0, 1, 1, 1, 1, 1];
    assert_eq!(
        starts(&more, &class_more, &ranges, 1, &d2_more, Some(1)),
        vec![1, 3, 4]
    );
    assert_eq!(
        starts(&params, &class_of, &ranges, 1, &d2, None),
        Vec::<usize>::new()
    );
    assert_eq!(
        starts(&params, &class_of, &ranges, 0, &d2, Some(0)),
        vec![0]
    );
}

const SAMPLES: usize = 100;
/// Each channel's size and its noise, a tenth of it.
const SCALE: [f64; 5] = [0.05, 0.01, 2e-5, 1e-3, 2e-3];

/// A made-up run of e3's class `class` at pose `p`, read by one whisker: a pulse whose time
/// follows the first unknown and whose width tells the class.
fn run(e3: &ShapeFamily, class: usize, p: &[f64], rng: Option<&mut Rng>) -> ShapeSample {
    run_as(e3, class, p, rng, 1.0, 1.0)
}

/// A run as [`run`] makes it, on a "whisker" whose pulses are `gain` times as high and
/// `widen` times as wide.
fn run_as(
    e3: &ShapeFamily,
    class: usize,
    p: &[f64],
    rng: Option<&mut Rng>,
    gain: f64,
    widen: f64,
) -> ShapeSample {
    let [lo, hi] = e3.classes()[class].family.ranges()[0];
    let u = (p[0] - lo) / (hi - lo);
    let centre = 20.0 + 50.0 * u;
    let width = widen * (3.0 + 2.0 * class as f64);
    let mut series: Vec<Vec<f64>> = SCALE
        .iter()
        .enumerate()
        .map(|(c, s)| {
            (0..SAMPLES)
                .map(|i| {
                    let x = (i as f64 - centre) / width;
                    gain * s * (1.0 + 0.2 * c as f64) * (-x * x).exp()
                })
                .collect()
        })
        .collect();
    if let Some(rng) = rng {
        for (ch, s) in series.iter_mut().zip(SCALE) {
            for v in ch.iter_mut() {
                *v += 0.1 * s * rng.normal();
            }
        }
    }
    ShapeSample {
        class,
        params: p.to_vec(),
        whiskers: vec![series],
    }
}

/// The synthetic family of these tests (`e3` read by `c3`): 60 noisy training runs per
/// class drawn with `rng`, their noise-free twins and 200 further noise-free runs per class.
fn synthetic(rng: &mut Rng) -> (ShapeFamily, Vec<ShapeSample>, CleanRuns) {
    let e3 = ShapeFamily::builtin("e3")
        .unwrap()
        .unwrap()
        .with_whiskers(&["c3"])
        .unwrap();
    let train_draws = e3.draws(60, false, 1);
    let training = train_draws
        .iter()
        .map(|(c, p)| run(&e3, *c, p, Some(&mut *rng)))
        .collect();
    let clean = CleanRuns {
        twins: train_draws
            .iter()
            .map(|(c, p)| run(&e3, *c, p, None))
            .collect(),
        extra: e3
            .draws(200, false, 2)
            .iter()
            .map(|(c, p)| run(&e3, *c, p, None))
            .collect(),
    };
    (e3, training, clean)
}

#[test]
fn the_bank_measures_the_noise_names_the_class_and_covers_the_pose_of_runs_it_did_not_hold() {
    let mut rng = Rng::new(7);
    let (e3, training, clean) = synthetic(&mut rng);
    let draws = |per: usize, seed: u64| e3.draws(per, false, seed);
    let model = ShapeBank::fit(&e3, &training, &clean).unwrap();
    // The noise it measured against the twins: the true tenth of each channel's size.
    let settings = model.settings();
    for (c, s) in SCALE.iter().enumerate() {
        let name = format!("noise_{}", CHANNELS[c]);
        let (_, got) = settings.iter().find(|(n, _)| *n == name).unwrap();
        assert!((got / (0.1 * s) - 1.0).abs() < 0.05, "{c}: {got}");
    }
    // Fresh noisy runs: the class, and the first unknown inside its interval.
    let mut right = 0;
    let mut covered = 0;
    let fresh = draws(20, 3);
    for (c, p) in &fresh {
        let r = run(&e3, *c, p, Some(&mut rng));
        let e = model.predict(&r.whiskers).unwrap();
        assert!((e.class.iter().map(|x| x.1).sum::<f64>() - 1.0).abs() < 1e-9);
        if e.best == *c {
            right += 1;
            covered += usize::from(e.pose[0].1.covers(p[0]));
        }
    }
    assert!(right >= 76, "{right} of 80 named right");
    // Read online: nothing is known before the pulses begin, and after the last sample the
    // posterior names the class as the whole recording's does.
    let mut agree = 0;
    for (c, p) in &fresh {
        let r = run(&e3, *c, p, Some(&mut rng));
        let trace = model.trace(&r.whiskers).unwrap();
        assert_eq!(trace.len(), SAMPLES);
        for row in &trace {
            assert!((row.iter().sum::<f64>() - 1.0).abs() < 1e-9);
        }
        assert!(
            trace[0].iter().all(|q| (q - 0.25).abs() < 0.05),
            "{:?}",
            trace[0]
        );
        let last = &trace[SAMPLES - 1];
        let top = (0..4).fold(0, |b, k| if last[k] > last[b] { k } else { b });
        agree += usize::from(top == model.predict(&r.whiskers).unwrap().best);
    }
    assert!(agree >= 72, "{agree} of 80 agree");
    assert!(
        (0.75..=1.0).contains(&(covered as f64 / right as f64)),
        "{covered} of {right} covered"
    );
    // What it was not fitted on is refused.
    let r = run(&e3, 0, &fresh[0].1, None);
    let short: Vec<Vec<Vec<f64>>> = vec![r.whiskers[0].iter().map(|c| c[..50].to_vec()).collect()];
    let err = model.predict(&short).unwrap_err().to_string();
    assert!(err.contains("100 samples"), "{err}");
    let mut nan = r.whiskers.clone();
    nan[0][1][3] = f64::NAN;
    assert!(model.predict(&nan).is_err());
    // Training runs without twins are refused.
    let none = CleanRuns {
        twins: Vec::new(),
        extra: clean.extra.clone(),
    };
    let err = ShapeBank::fit(&e3, &training, &none)
        .unwrap_err()
        .to_string();
    assert!(err.contains("twin"), "{err}");
}

#[test]
fn a_recording_the_bank_cannot_explain_is_read_with_wider_probabilities_and_intervals() {
    let mut rng = Rng::new(11);
    let (e3, training, clean) = synthetic(&mut rng);
    let draws = |per: usize, seed: u64| e3.draws(per, false, seed);
    let model = ShapeBank::fit(&e3, &training, &clean).unwrap();
    assert!(model.misfit.is_finite() && model.misfit > 0.0);
    assert_eq!(model.misfit_trace.len(), SAMPLES);
    // The same poses recorded by the bank's own "whisker" and by one whose pulses are a
    // quarter higher and a third wider.
    let fresh = draws(10, 3);
    let (mut own, mut other) = (Vec::new(), Vec::new());
    for (c, p) in &fresh {
        let a = run(&e3, *c, p, Some(&mut rng));
        let b = run_as(&e3, *c, p, Some(&mut rng), 1.25, 1.33);
        own.push(model.predict(&a.whiskers).unwrap());
        other.push(model.predict(&b.whiskers).unwrap());
    }
    let misfit = |e: &ShapeEstimate| e.misfit.unwrap();
    let top = |e: &ShapeEstimate| e.class[e.best].1;
    let mean = |v: &[ShapeEstimate], f: &dyn Fn(&ShapeEstimate) -> f64| {
        v.iter().map(f).sum::<f64>() / v.len() as f64
    };
    // Its own recordings lie about as far from the bank as the held-out runs did.
    assert!(own.iter().all(|e| misfit(e) >= 1.0));
    assert!(mean(&own, &misfit) < 2.0, "{}", mean(&own, &misfit));
    // The other whisker's lie far beyond, and are read less surely, with wider intervals.
    assert!(other.iter().all(|e| misfit(e) > 1.5));
    assert!(mean(&other, &misfit) > 3.0, "{}", mean(&other, &misfit));
    assert!(mean(&other, &top) < mean(&own, &top));
    for (a, b) in own.iter().zip(&other) {
        if a.best == b.best {
            let ratio = b.pose[0].1.std / a.pose[0].1.std;
            let expected = (misfit(b) / misfit(a)).sqrt();
            assert!(
                (ratio / expected - 1.0).abs() < 1e-9,
                "{ratio} vs {expected}"
            );
        }
    }
    // Online alike: the last sample's posterior is no surer than the whole recording's
    // reference allows, and every row still sums to 1.
    let b = run_as(&e3, fresh[0].0, &fresh[0].1, Some(&mut rng), 1.25, 1.33);
    for row in model.trace(&b.whiskers).unwrap() {
        assert!((row.iter().sum::<f64>() - 1.0).abs() < 1e-9);
    }
}

#[test]
fn readings_of_other_whiskers_teach_how_far_a_far_recording_can_be_trusted() {
    let mut rng = Rng::new(13);
    let (e3, training, clean) = synthetic(&mut rng);
    // "Other whiskers": pulses a quarter higher and a third wider, noise-free (the fit adds
    // its training runs' noise).
    let other = |draws: &[(usize, Vec<f64>)], rng: Option<&mut Rng>| -> Vec<ShapeSample> {
        let mut rng = rng;
        draws
            .iter()
            .map(|(c, p)| run_as(&e3, *c, p, rng.as_deref_mut(), 1.25, 1.33))
            .collect()
    };
    let drawn = other(&e3.draws(30, false, 21), None);
    let plain = ShapeBank::fit(&e3, &training, &clean).unwrap();
    let taught = ShapeBank::fit_with(&e3, &training, &clean, Some(drawn)).unwrap();
    // Without a family it can simulate and no runs given, nothing is learnt.
    assert_eq!(
        (plain.trust, plain.widen_power, plain.off_nominal.0),
        (Trust::default(), 0.5, 0)
    );
    assert_eq!(taught.off_nominal.0, 120);
    assert!(
        taught.trust.power > 0.0 || taught.trust.step > 0.0,
        "{:?}",
        taught.trust
    );
    assert!(taught.off_nominal.2 > 1.5, "{:?}", taught.off_nominal);
    // Fresh recordings of the other whisker: lower log loss once taught; the class named and
    // the pose are the same, its intervals at least as wide.
    let fresh = e3.draws(15, false, 22);
    let loss = |m: &ShapeBank, runs: &[ShapeSample]| -> f64 {
        runs.iter()
            .map(|s| {
                let e = m.predict(&s.whiskers).unwrap();
                -e.class[s.class].1.max(1e-300).ln()
            })
            .sum::<f64>()
            / runs.len() as f64
    };
    let far = other(&fresh, Some(&mut rng));
    assert!(loss(&taught, &far) < loss(&plain, &far));
    for s in &far {
        let (a, b) = (
            plain.predict(&s.whiskers).unwrap(),
            taught.predict(&s.whiskers).unwrap(),
        );
        assert_eq!(a.best, b.best);
        assert_eq!(a.pose[0].1.mean, b.pose[0].1.mean);
        assert!(b.pose[0].1.std >= a.pose[0].1.std);
        assert!((b.class.iter().map(|x| x.1).sum::<f64>() - 1.0).abs() < 1e-9);
        assert!(b.class[b.best].1 <= a.class[a.best].1 + 1e-12);
    }
    // Its own recordings are named as before; over both kinds of recording (the other
    // whisker's lie at misfits that overlap its own here), the log loss falls.
    let own: Vec<ShapeSample> = fresh
        .iter()
        .map(|(c, p)| run(&e3, *c, p, Some(&mut rng)))
        .collect();
    for s in &own {
        let (a, b) = (
            plain.predict(&s.whiskers).unwrap(),
            taught.predict(&s.whiskers).unwrap(),
        );
        assert_eq!(a.best, b.best);
    }
    let both = |m: &ShapeBank| loss(m, &own) + loss(m, &far);
    assert!(
        both(&taught) < both(&plain),
        "{} vs {}",
        both(&taught),
        both(&plain)
    );
    // Online alike: every row sums to 1.
    for row in taught.trace(&far[0].whiskers).unwrap() {
        assert!((row.iter().sum::<f64>() - 1.0).abs() < 1e-9);
    }
}

/// [`run`] with noise coloured as a whisker's ringing colours it: each channel's noise an
/// autoregression whose samples a few milliseconds apart stay alike.
fn ringing_run(e3: &ShapeFamily, class: usize, p: &[f64], rng: &mut Rng) -> ShapeSample {
    let mut s = run(e3, class, p, None);
    for (ch, size) in s.whiskers[0].iter_mut().zip(SCALE) {
        let mut e = 0.0;
        for v in ch.iter_mut() {
            e = 0.9 * e + (1.0f64 - 0.81).sqrt() * rng.normal();
            *v += 0.1 * size * e;
        }
    }
    s
}

#[test]
fn fresh_recordings_of_its_own_whisker_lie_as_far_from_the_bank_as_its_held_out_runs() {
    // The noise's covariance is read on residuals of other runs than the held-out ones: read
    // on the same residuals, it whitens them smaller than a fresh recording's (the more so
    // the more its samples are alike), and every recording of the bank's own whisker then
    // looks far from it.
    let mut rng = Rng::new(17);
    let (e3, _, clean) = synthetic(&mut rng);
    let training: Vec<ShapeSample> = clean
        .twins
        .iter()
        .map(|s| ringing_run(&e3, s.class, &s.params, &mut rng))
        .collect();
    let model = ShapeBank::fit(&e3, &training, &clean).unwrap();
    let mut ratios: Vec<f64> = e3
        .draws(30, false, 5)
        .iter()
        .map(|(c, p)| {
            let r = ringing_run(&e3, *c, p, &mut rng);
            model.predict(&r.whiskers).unwrap().misfit.unwrap()
        })
        .collect();
    ratios.sort_by(|a, b| a.total_cmp(b));
    // Half the held-out runs lie within the reference (ratio 1); of fresh runs, about as many.
    let within = ratios.iter().filter(|&&r| r <= 1.0).count();
    assert!(
        (36..=84).contains(&within),
        "{within} of 120 within the held-out median; median ratio {}",
        ratios[60]
    );
}
