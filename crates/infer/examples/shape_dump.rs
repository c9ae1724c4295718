//! Writes a shape family's noisy training and evaluated runs as raw little-endian f64 arrays
//! (`[runs][whiskers][channels][samples]`) with their classes and poses, for exploring
//! classifiers outside the crate.
//!
//! `cargo run --release -p vibrissa-infer --example shape_dump -- OUT [TRAIN_PER_CLASS] [EVAL_PER_CLASS] [noisy|clean]`
use std::io::Write;
use vibrissa_infer::experiment::Variant;
use vibrissa_infer::shapes::{ShapeFamily, ShapeSample};
use vibrissa_infer::Family;

fn write(dir: &std::path::Path, name: &str, runs: &[ShapeSample]) {
    let mut raw = std::fs::File::create(dir.join(format!("{name}.f64"))).unwrap();
    let mut meta = std::fs::File::create(dir.join(format!("{name}.csv"))).unwrap();
    for s in runs {
        for w in &s.whiskers {
            for c in w {
                for x in c {
                    raw.write_all(&x.to_le_bytes()).unwrap();
                }
            }
        }
        let p: Vec<String> = s.params.iter().map(|x| x.to_string()).collect();
        writeln!(meta, "{},{}", s.class, p.join(",")).unwrap();
    }
}

fn main() {
    let a: Vec<String> = std::env::args().collect();
    let out = std::path::PathBuf::from(&a[1]);
    let train: usize = a.get(2).map_or(800, |s| s.parse().unwrap());
    let eval: usize = a.get(3).map_or(50, |s| s.parse().unwrap());
    let variant = if a.get(4).map_or("noisy", |s| s) == "clean" {
        Variant::Clean
    } else {
        Variant::Noisy
    };
    std::fs::create_dir_all(&out).unwrap();
    let family = ShapeFamily::builtin("e3").unwrap().unwrap();
    let noise = Family::builtin("e2").unwrap().noise(variant).unwrap();
    let eval_draws = family.draws(eval, false, 1 ^ 0xe3a1);
    let (evaluated, _) = family
        .simulate_completed(&eval_draws, &noise, 1 ^ 0xe3a2, &|| {})
        .unwrap();
    let measured = ShapeSample::measured_noise(&evaluated).unwrap();
    let trained_noise = family.training_noise(measured, noise.process).unwrap();
    let draws = family.draws(train, true, 1 ^ 0xe3b1);
    let (training, _) = family
        .simulate_completed(&draws, &trained_noise, 1 ^ 0xe3b2, &|| {})
        .unwrap();
    // The same training poses without any noise.
    let (clean, _) = family
        .simulate_completed(
            &draws,
            &Family::builtin("e2")
                .unwrap()
                .noise(Variant::Clean)
                .unwrap(),
            1 ^ 0xe3b2,
            &|| {},
        )
        .unwrap();
    write(&out, "train", &training);
    write(&out, "train_clean", &clean);
    write(&out, "eval", &evaluated);
    println!(
        "measured {:?}, trained {:?}, samples {}",
        measured,
        trained_noise.sensor,
        evaluated[0].whiskers[0][0].len()
    );
}
