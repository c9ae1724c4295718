use vibrissa_core::objects::{Motion, Object, Shape};
use vibrissa_core::sim::{run, Scenario};
fn main() {
    let args: Vec<f64> = std::env::args()
        .skip(1)
        .map(|x| x.parse().unwrap())
        .collect();
    let (d, v) = (args[0], args[1]);
    let dt = args.get(2).copied().unwrap_or(1e-4);
    let mut sc = Scenario::default();
    sc.integrator.dt = dt;
    sc.objects.push(Object {
        shape: Shape::Box {
            width: 0.01,
            height: 0.01,
        },
        position: [d + 0.005, -0.006],
        angle: 0.0,
        motion: Motion::Constant {
            velocity: [0.0, v],
            angular_velocity: 0.0,
        },
        friction: 0.0,
    });
    let t0 = std::time::Instant::now();
    let out = run(&sc, &mut |_| {}).unwrap();
    let el = t0.elapsed().as_secs_f64();
    let contact: Vec<usize> = out
        .rows
        .iter()
        .enumerate()
        .filter(|(_, r)| r[6] > 0.5)
        .map(|(i, _)| i)
        .collect();
    println!("d={d} v={v} dt={} steps={} time={:.3}s maxpen={:.3e} m contact samples {}..{} ({} samples)", out.dt, out.steps, el, out.max_penetration, contact.first().unwrap_or(&0), contact.last().unwrap_or(&0), contact.len());
    if args.len() > 3 {
        for r in out.rows.iter().step_by(5) {
            println!(
                "{:.3} {:+.5e} {:+.5e} {:+.4e} {:+.4e} {:+.4e} {} {:.5} {:.5} {:.5}",
                r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8], r[9]
            );
        }
    }
}
