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
