use vibrissa_core::dynamics::Integrator;
use vibrissa_core::scenes::e2_box;
use vibrissa_core::sim::{self, Scenario};
fn main() {
    let dt: f64 = std::env::args()
        .nth(1)
        .map(|s| s.parse().unwrap())
        .unwrap_or(1e-4);
    let t0 = std::time::Instant::now();
    let mut steps = 0;
    for _ in 0..10 {
        for &(d, v) in &[(0.015, 0.3), (0.023, 0.9), (0.029, 1.5), (0.02, 0.6)] {
            let sc = Scenario {
                objects: vec![e2_box(d, v)],
                integrator: Integrator {
                    dt,
                    ..Integrator::default()
                },
                ..Scenario::default()
            };
            let o = sim::run(&sc, &mut |_| {}).unwrap();
            steps += o.steps;
        }
    }
    println!(
        "{steps} steps, {:.2} us/step",
        t0.elapsed().as_secs_f64() * 1e6 / steps as f64
    );
}
