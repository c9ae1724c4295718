use vibrissa_core::dynamics::*;
use vibrissa_core::objects::{Motion, Object, Shape};
use vibrissa_core::sensors::Sensors;
use vibrissa_core::sim::BaseDrive;
use vibrissa_core::whisker::Damping;
use vibrissa_core::*;
fn main() {
    let mu: f64 = std::env::args().nth(1).unwrap().parse().unwrap();
    let rate: f64 = std::env::args().nth(2).unwrap().parse().unwrap();
    let mut p = WhiskerParams::w30();
    p.damping = Damping::ModalRatio { ratio: 0.7 };
    let w = p.check().unwrap();
    let m = Model::new(&w, 20, Discretisation::Gregory).unwrap();
    let objects = [Object {
        shape: Shape::Circle { radius: 0.5e-3 },
        position: [0.020, 0.62e-3],
        angle: 0.0,
        motion: Motion::default(),
        friction: mu,
    }];
    let drive = BaseDrive::Ramp {
        rate,
        start: 0.0,
        stop: f64::INFINITY,
        smoothing: 0.02,
    };
    let st = Integrator::with_dt(
        std::env::var("DT")
            .map(|x| x.parse().unwrap())
            .unwrap_or(1e-4),
    )
    .check()
    .unwrap();
    let mut s = State::at_rest(&m, 0);
    let mut ws = Workspace::new(&m);
    for k in 1..=((0.6 / st.dt) as usize) {
        let inputs = Inputs {
            base: drive.at(k as f64 * st.dt),
            objects: &objects,
            ..Default::default()
        };
        step(&m, &st, &mut s, &inputs, &mut ws).unwrap();
        if (s.t * 1e4).round() as usize % 100 == 0
            && ((s.t / st.dt) - (s.t / st.dt).round()).abs() < 1e-6
            && (s.t * 1e4 - (s.t * 1e4).round()).abs() < 1e-6
        {
            let sen = Sensors::read(&s);
            match s.contact { Some(c) => println!("t={:.4} psi={:.4} s={:.5} n=({:+.3},{:+.3}) fn={:.3e} ft={:+.3e} m0={:+.3e} m0/fs={:.4} count={} it={}", s.t, s.base.angle, c.s, c.normal[0], c.normal[1], c.normal_force, c.tangential_force, sen.m0, sen.m0.abs()/(c.normal_force.hypot(c.tangential_force)*c.s), c.count, ws.iterations),
              None => println!("t={:.4} psi={:.4} no contact m0={:+.3e} it={}", s.t, s.base.angle, sen.m0, ws.iterations) }
        }
    }
}
