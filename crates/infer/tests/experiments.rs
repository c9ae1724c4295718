//! The seed's experiments end to end.

use vibrissa_infer::{evaluate, Budget, Family, Variant};

#[test]
fn e1_clean_template_method_has_a_finite_error_and_is_beaten_under_the_same_budget() {
    let e1 = Family::builtin("e1").unwrap();
    let ev = evaluate(&e1, Variant::Clean, 1, &|_, _, _| {}).unwrap();
    for m in &ev.methods {
        eprintln!(
            "{:16} {:5} mae {:?} cov {:?} fit {:.3}s pred {:.2e}s {:?}",
            m.name,
            m.budget.name(),
            m.mae,
            m.coverage,
            m.fit_seconds,
            m.predict_seconds,
            m.settings
        );
    }
    eprintln!("sigma2 {} total {:.2}s", ev.sigma2, ev.seconds);
    let template = ev.methods.iter().find(|m| m.name == "template").unwrap();
    assert!(template.mae[0].is_finite() && template.mae[0] > 0.0);
    assert!(ev.sigma2 > 0.0 && ev.sigma2.is_finite());
    // Responsibilities sum to one for every grid run.
    for r in &ev.responsibilities {
        assert!((r.iter().sum::<f64>() - 1.0).abs() < 1e-9);
    }
    let best = ev.best(Budget::Paper).unwrap();
    assert_ne!(best.name, "template");
    assert!(best.mae[0] < template.mae[0]);
}

#[test]
fn estimators_measure_the_noise_of_the_recordings_they_are_given() {
    let e1 = Family::builtin("e1").unwrap();
    let noisy = evaluate(&e1, Variant::Noisy, 2, &|_, _, _| {}).unwrap();
    // The recordings carry the variant's sensor and process noise; the estimators are given
    // the sensor noise they measure on them and the experiment's random forces, which are part
    // of its scenario rather than of its sensors. The angles and the moment
    // read as their sensor noise (within 20%); the random forces on the segments move the base
    // forces fast enough to read as further sensor noise there (about 2.4 and 1.7 times).
    for (c, (made, measured)) in noisy
        .noise
        .sensor
        .iter()
        .zip(noisy.estimated_noise.sensor)
        .enumerate()
    {
        let ratio = measured / made;
        eprintln!("channel {c}: made {made}, measured {measured}");
        let within = if c < 3 { 0.8..1.2 } else { 0.8..3.0 };
        assert!(within.contains(&ratio), "channel {c}: {ratio}");
    }
    assert!(noisy.noise.process > 0.0);
    assert_eq!(noisy.estimated_noise.process, noisy.noise.process);
    // Clean recordings read as far less noisy than the noisy variant.
    let clean = evaluate(&e1, Variant::Clean, 2, &|_, _, _| {}).unwrap();
    for (c, (clean, noisy)) in clean
        .estimated_noise
        .sensor
        .iter()
        .zip(noisy.noise.sensor)
        .enumerate()
    {
        assert!(*clean < 0.1 * noisy, "channel {c}: {clean} vs {noisy}");
    }
}
