use vibrissa_core::dynamics::Integrator;
use vibrissa_core::scenes::e2_box;
use vibrissa_core::sim::{self, Scenario};
use vibrissa_infer::experiment::{Noise, Variant};
fn main() {
    let noise = Noise::of(Variant::Noisy).unwrap();
    let pts: Vec<(f64, f64)> = [0.015, 0.019, 0.023, 0.027, 0.030]
        .iter()
        .flat_map(|&d| [0.3, 0.9, 1.5].iter().map(move |&v| (d, v)))
        .collect();
    let refs: Vec<_> = pts
        .iter()
        .map(|&(d, v)| {
            sim::run(
                &Scenario {
                    objects: vec![e2_box(d, v)],
                    ..Scenario::default()
                },
                &mut |_| {},
            )
            .unwrap()
        })
        .collect();
    for &dt in &[1e-4, 2.5e-4, 5e-4, 1e-3] {
        for &it in &[1usize, 2, 3, 6] {
            let mut worst: f64 = 0.0;
            let mut mean = 0.0;
            let mut steps = 0;
            let t0 = std::time::Instant::now();
            for (k, &(d, v)) in pts.iter().enumerate() {
                let sc = Scenario {
                    objects: vec![e2_box(d, v)],
                    integrator: Integrator {
                        dt,
                        max_iterations: it,
                        ..Integrator::default()
                    },
                    ..Scenario::default()
                };
                let o = sim::run(&sc, &mut |_| {}).unwrap();
                steps += o.steps;
                let mut tot = 0.0;
                for c in 0..5 {
                    let mut r = 0.0;
                    for (a, b) in refs[k].rows.iter().zip(&o.rows) {
                        r += ((a[c + 1] - b[c + 1]) / noise.sensor[c]).powi(2);
                    }
                    let r = (r / 151.0).sqrt();
                    worst = worst.max(r);
                    tot += r / 5.0;
                }
                mean += tot / pts.len() as f64;
            }
            let us = t0.elapsed().as_secs_f64() * 1e6;
            println!("dt={dt:e} it={it}: mean rms/sigma {mean:.3} worst {worst:.3}; {:.2} us/step, {:.2} us per 1ms of data", us / steps as f64, us / (pts.len() as f64 * 150.0));
        }
    }
}
