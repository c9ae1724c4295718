use vibrissa_infer::experiment::{simulate, Experiment, Noise, Variant};
use vibrissa_infer::pf::{self, Config, Observations};
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let np: usize = args.get(1).map(|s| s.parse().unwrap()).unwrap_or(1000);
    let infl: f64 = args.get(2).map(|s| s.parse().unwrap()).unwrap_or(1.2);
    let dt: f64 = args.get(3).map(|s| s.parse().unwrap()).unwrap_or(5e-4);
    let it: usize = args.get(4).map(|s| s.parse().unwrap()).unwrap_or(2);
    let shrink: f64 = args.get(5).map(|s| s.parse().unwrap()).unwrap_or(0.98);
    let noise = Noise::of(Variant::Noisy).unwrap();
    let sigma = noise.sensor.map(|s| s * infl);
    let pts = [
        (0.016, 0.6),
        (0.021, 1.2),
        (0.026, 0.3),
        (0.029, 1.5),
        (0.018, 0.9),
        (0.024, 0.6),
        (0.028, 1.2),
        (0.017, 0.3),
    ];
    let (mut ed, mut ev, mut cd, mut cv, mut tt) = (0.0, 0.0, 0, 0, 0.0);
    for (k, &(d, v)) in pts.iter().enumerate() {
        let s = simulate(Experiment::E2, [d, v], &noise, 1000 + k as u64).unwrap();
        let mut cfg = Config::e2(sigma, np, 7);
        cfg.dt = dt;
        cfg.max_iterations = it;
        cfg.shrink = shrink;
        cfg.sigma = noise.sensor.map(|s| s * infl * 1.118);
        let obs = Observations::at_rate(s.series.clone(), 1000.0);
        let t0 = std::time::Instant::now();
        let post = pf::run(&cfg, &obs, &mut |_| {}).unwrap();
        let el = t0.elapsed().as_secs_f64();
        tt += el;
        let e = post.last();
        ed += (e[0].mean - d).abs();
        ev += (e[1].mean - v).abs();
        cd += e[0].covers(d) as usize;
        cv += e[1].covers(v) as usize;
        println!("d={d} v={v}: d^={:.5}±{:.5} v^={:.4}±{:.4} resamples {} div {} ess_end {:.0} {:.3}s RTF {:.2}", e[0].mean, e[0].std, e[1].mean, e[1].std, post.resamples, post.diverged, post.trace.last().unwrap().ess, el, 0.15/el);
    }
    let n = pts.len() as f64;
    println!(
        "MAE d {:.3} mm, v {:.4} m/s, cover {}/{} {}/{}, mean RTF {:.2}",
        ed / n * 1e3,
        ev / n,
        cd,
        pts.len(),
        cv,
        pts.len(),
        0.15 * n / tt
    );
}
