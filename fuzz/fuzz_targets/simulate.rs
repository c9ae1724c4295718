//! The stepper end to end: any scenario text that loads simulates a few milliseconds to
//! finite output, or stops with an error (a divergence named as such); never a panic, never a
//! non-finite value in the output.
#![no_main]

use libfuzzer_sys::fuzz_target;
use vibrissa_core::sim;

/// Largest chain simulated (larger ones are slow, not more telling).
const MAX_SEGMENTS: usize = 40;
/// Steps simulated at most.
const MAX_STEPS: f64 = 200.0;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Ok(mut scenario) = vibrissa_io::load_str(text, "fuzz.toml", &[]) else {
        return;
    };
    if scenario.segments > MAX_SEGMENTS {
        return;
    }
    // A few milliseconds at most, and at least one sample period.
    let period = 1.0 / scenario.sample_rate;
    scenario.duration = scenario
        .duration
        .min(MAX_STEPS * scenario.integrator.dt)
        .max(period);
    if scenario.duration / scenario.integrator.dt.min(period) > 4.0 * MAX_STEPS {
        return;
    }
    if let Ok(out) = sim::run(&scenario, &mut |_| {}) {
        for row in &out.rows {
            // Contact columns are NaN where there is no contact; the others are always numbers.
            assert!(
                row[..7].iter().all(|x| x.is_finite()),
                "non-finite output {row:?}"
            );
        }
    }
});
