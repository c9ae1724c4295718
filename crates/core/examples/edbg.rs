use vibrissa_core::beam::BeamProfile;
use vibrissa_core::dynamics::*;
use vibrissa_core::objects::{Motion, Object, Shape};
use vibrissa_core::whisker::Damping;
use vibrissa_core::*;
fn main() {
    let mut p = WhiskerParams::w30();
    p.damping = Damping::None;
    let w = p.check().unwrap();
    let m = Model::new(&w, 20, Discretisation::Gregory).unwrap();
    let l = w.length();
    let eq = statics::solve(
        &m,
        &[PointLoad {
            segment: 19,
            along: m.len[19],
            force: [0.0, 0.3 * w.ei(0.0) / (l * l)],
        }],
    )
    .unwrap();
    let objects = [Object {
        shape: Shape::Circle { radius: 0.5e-3 },
        position: [0.022, -1.0e-3],
        angle: 0.0,
        motion: Motion::default(),
        friction: 0.0,
    }];
    let st = Integrator::with_dt(1e-4).check().unwrap();
    let mut s = State::at_rest(&m, 0);
    s.q_mut().copy_from_slice(&eq.q);
    let mut ws = Workspace::new(&m);
    let inputs = Inputs {
        objects: &objects,
        ..Default::default()
    };
    initialize(&m, &mut s, &inputs, &mut ws).unwrap();
    let mut last = potential_energy(&m, &s);
    for k in 0..3000 {
        step(&m, &st, &mut s, &inputs, &mut ws).unwrap();
        let e = potential_energy(&m, &s) + kinetic_energy(&m, &s, &mut ws);
        let pen = sim::penetration(&m, &s, &mut ws, &objects);
        if s.contact.is_some() || e > last * (1.0 + 1e-9) {
            println!(
                "k={k} t={:.4} E={:.6e} dE/E={:+.3e} it={} pen={:.2e} contact={:?}",
                s.t,
                e,
                e / last - 1.0,
                ws.iterations,
                pen,
                s.contact.map(|c| (c.s, c.normal_force, c.count))
            );
        }
        last = e;
        if k > 400 {
            break;
        }
    }
}
