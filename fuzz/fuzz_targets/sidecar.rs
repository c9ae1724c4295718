//! Sidecars (a series' metadata in JSON beside it): any bytes in `run.json` beside a valid
//! `run.csv` leave the series' columns and values untouched, and at worst give warnings; never a
//! panic.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::PathBuf;
use std::sync::OnceLock;
use vibrissa_io::series::{merge_sidecar, read_csv};

const RUN: &str = "t,theta01,theta12\n0,0,0\n0.001,1e-4,2e-4\n0.002,3e-4,-1e-4\n";

/// A folder of this process with the valid series `run.csv`.
fn folder() -> &'static PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir =
            std::env::temp_dir().join(format!("vibrissa-fuzz-sidecar-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temporary folder");
        std::fs::write(dir.join("run.csv"), RUN).expect("run.csv");
        dir
    })
}

fuzz_target!(|data: &[u8]| {
    let dir = folder();
    let csv = dir.join("run.csv");
    std::fs::write(dir.join("run.json"), data).expect("run.json");
    let mut series = read_csv(&csv).expect("run.csv reads");
    let before = series.clone();
    let _warnings = merge_sidecar(&mut series, &csv);
    assert_eq!(series.columns, before.columns);
    assert_eq!(series.data, before.data);
});
