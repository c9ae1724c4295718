use vibrissa_core::dynamics::*;
use vibrissa_core::objects::{Motion, Object, Shape};
use vibrissa_core::*;
fn main() {
    let args: Vec<f64> = std::env::args()
        .skip(1)
        .map(|x| x.parse().unwrap())
        .collect();
    let (d, v, maxit, tol) = (args[0], args[1], args[2] as usize, args[3]);
    let w = WhiskerParams::w30().check().unwrap();
    let m = Model::new(&w, 20, Discretisation::Gregory).unwrap();
    let objs = [Object {
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
    }];
    let st = Integrator {
        dt: 1e-4,
        max_iterations: maxit,
        tolerance: tol,
        ..Default::default()
    }
    .check()
    .unwrap();
    let mut s = State::at_rest(&m, 0);
    let mut ws = Workspace::new(&m);
    let inp = Inputs {
        objects: &objs,
        ..Default::default()
    };
    let mut worst = 0.0f64;
    let mut its = 0;
    for k in 0..1500 {
        step(&m, &st, &mut s, &inp, &mut ws).unwrap();
        its += ws.iterations;
        let it = ws.iterations;
        let p = sim::penetration(&m, &s, &mut ws, &objs);
        if p > worst {
            worst = p;
        }
        if p > 2e-7 && args.len() > 4 {
            println!(
                "step {k} t={:.4} pen={:.3e} iters={} contact={:?}",
                s.t,
                p,
                it,
                s.contact.map(|c| (c.s, c.count))
            );
        }
    }
    println!(
        "d={d} v={v} maxit={maxit} tol={tol}: max pen {:.3e}, iters/step {:.2}",
        worst,
        its as f64 / 1500.0
    );
}
