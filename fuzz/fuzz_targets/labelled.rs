//! Labelled folders (`truth.csv` naming recordings and their labels): any bytes as `truth.csv`
//! beside two valid recordings give the labelled set or an error naming the folder; never a
//! panic. Every label read is a finite number for a key of the nominal scenario.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::PathBuf;
use std::sync::OnceLock;
use vibrissa_io::labelled::{read_labelled, Options};
use vibrissa_io::scenario::Document;

/// A folder of this process with two short valid recordings, `a.csv` and `b.csv`, and the
/// nominal scenario (the built-in `e2`).
fn setup() -> &'static (PathBuf, Document) {
    static SETUP: OnceLock<(PathBuf, Document)> = OnceLock::new();
    SETUP.get_or_init(|| {
        let dir =
            std::env::temp_dir().join(format!("vibrissa-fuzz-labelled-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temporary folder");
        let mut run = String::from("t,theta01,theta12,m0,fx,fy\n");
        for k in 0..40 {
            let t = k as f64 * 1e-3;
            let x = (t * 300.0).sin() * 1e-3;
            run += &format!(
                "{t},{x},{},{},{},{}\n",
                2.0 * x,
                x * 1e-4,
                x * 1e-2,
                -x * 1e-2
            );
        }
        std::fs::write(dir.join("a.csv"), &run).expect("a.csv");
        std::fs::write(dir.join("b.csv"), &run).expect("b.csv");
        let nominal = Document::load("e2", &[]).expect("the built-in e2");
        (dir, nominal)
    })
}

fuzz_target!(|data: &[u8]| {
    let (dir, nominal) = setup();
    std::fs::write(dir.join("truth.csv"), data).expect("truth.csv");
    let options = Options {
        ignore_unlisted: true,
    };
    if let Ok(set) = read_labelled(dir, nominal, &options) {
        for r in &set.recordings {
            for (key, value) in &r.labels {
                assert!(value.is_finite(), "label {key} = {value}");
            }
        }
    }
});
