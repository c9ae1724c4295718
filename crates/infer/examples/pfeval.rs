use std::sync::Arc;
use vibrissa_core::rng::Rng;
use vibrissa_infer::experiment::{simulate_all, simulate_delayed, Experiment, Noise, Variant};
use vibrissa_infer::pf::Pf;
use vibrissa_infer::{methods, Method, Training};
fn main() {
    let a: Vec<String> = std::env::args().collect();
    let set = a.get(1).cloned().unwrap_or("train".into());
    let np: usize = a.get(2).map(|s| s.parse().unwrap()).unwrap_or(500);
    let temper: f64 = a.get(3).map(|s| s.parse().unwrap()).unwrap_or(2.5);
    let delay: f64 = a.get(4).map(|s| s.parse().unwrap()).unwrap_or(0.0);
    let inject: f64 = a.get(5).map(|s| s.parse().unwrap()).unwrap_or(0.0);
    let variant = Variant::parse(a.get(6).map(|s| s.as_str()).unwrap_or("noisy")).unwrap();
    let e = Experiment::E2;
    let noise = Noise::of(variant).unwrap();
    let params: Vec<[f64; 2]> = if set == "train" {
        e.random_params(24, 4242)
    } else {
        e.grid()
            .into_iter()
            .filter(|p| !e.is_template(*p))
            .collect()
    };
    let train_p = e.random_params(400, 1 ^ 0x5eed);
    let train = simulate_all(e, &train_p, &noise, 2, &|| {}).unwrap();
    let training = Training {
        experiment: e,
        samples: train,
        calibration: vec![],
    };
    let mut pf = Pf::new(np);
    pf.temper = temper;
    if let Ok(x) = std::env::var("PF_SEED") {
        pf.seed = x.parse().unwrap();
    }
    if let Ok(x) = std::env::var("PF_DT") {
        pf.dt = x.parse().unwrap();
    }
    if let Ok(x) = std::env::var("PF_IT") {
        pf.max_iterations = x.parse().unwrap();
    }
    pf.max_delay = if delay > 0.0 { 0.05 } else { 0.0 };
    if inject > 0.0 {
        let m: Arc<dyn Method> = Arc::from(methods::by_name("krr").unwrap());
        pf.inject = Some((inject, m));
    }
    pf.fit(&training).unwrap();
    let t0 = std::time::Instant::now();
    let (mut ed, mut ev, mut cd, mut cv, mut data_s) = (0.0, 0.0, 0, 0, 0.0);
    let mut rng = Rng::stream(77, 0);
    for (k, p) in params.iter().enumerate() {
        let dl = if delay > 0.0 {
            (rng.uniform() * delay * 1000.0).round() / 1000.0
        } else {
            0.0
        };
        let s = simulate_delayed(e, *p, dl, &noise, 5000 + k as u64).unwrap();
        data_s += (s.series[0].len() - 1) as f64 * 1e-3;
        let est = pf.predict(&s.series).unwrap();
        ed += (est[0].mean - p[0]).abs();
        ev += (est[1].mean - p[1]).abs();
        cd += est[0].covers(p[0]) as usize;
        cv += est[1].covers(p[1]) as usize;
        if (est[0].mean - p[0]).abs() > 5e-4 || (est[1].mean - p[1]).abs() > 0.03 {
            println!(
                "  d={:.4} v={:.3} delay={dl}: d^={:.5}±{:.5} v^={:.4}±{:.4}",
                p[0], p[1], est[0].mean, est[0].std, est[1].mean, est[1].std
            );
        }
    }
    let n = params.len() as f64;
    let el = t0.elapsed().as_secs_f64();
    println!("{set} n={} particles={np} temper={temper} delay<={delay} inject={inject}: MAE d {:.3} mm v {:.4} m/s; cover {:.0}% {:.0}%; {:.1}s, RTF {:.2}", params.len(), ed/n*1e3, ev/n, cd as f64/n*100.0, cv as f64/n*100.0, el, data_s/el);
}
