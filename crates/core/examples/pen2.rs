use vibrissa_core::dynamics::*;
use vibrissa_core::objects::closest;
use vibrissa_core::*;
fn main() {
    let w = WhiskerParams::w30().check().unwrap();
    let m = Model::new(&w, 20, Discretisation::Gregory).unwrap();
    let objs = [scenes::e2_box(0.021, 1.5)];
    let st = Integrator::with_dt(1e-4).check().unwrap();
    let mut s = State::at_rest(&m, 0);
    let mut ws = Workspace::new(&m);
    let inp = Inputs {
        objects: &objs,
        ..Default::default()
    };
    for _ in 0..8 {
        step(&m, &st, &mut s, &inp, &mut ws).unwrap();
        ws.evaluate(&m, &s);
        let pose = objs[0].pose(s.t);
        for i in 0..20 {
            let c = closest(&objs[0].shape, &pose, ws.nodes()[i], ws.nodes()[i + 1]);
            let g = c.distance - m.radius[i];
            if g < 1e-6 {
                println!(
                    "t={:.4} seg {i} u={:.3} gap={:.3e} n=({:.3},{:.3}) w=({:.5},{:.6})",
                    s.t, c.u, g, c.normal[0], c.normal[1], c.on_whisker[0], c.on_whisker[1]
                );
            }
        }
    }
}
