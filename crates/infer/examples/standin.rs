//! Writes a stand-in "foreign" whisker's labelled recordings (see `vibrissa_infer::standin`).
//!
//! ```sh
//! cargo run --release -p vibrissa-infer --example standin -- --seed 3 --out DIR \
//!     [--nominal e2|FILE.toml] [--segments 50] [--discretisation seed] [--off-grid 20] \
//!     [--calib-noise 0] [--eval-noise 0.03] [--nominal-whisker] [--max-lead 0.04] \
//!     [--compliance 6] [--dt 1e-5]
//! ```
//!
//! DIR receives `calib/` (9 template strikes, clean unless `--calib-noise`), `eval/` (off-grid
//! noisy strikes), `nominal.toml`, `standin.toml` (the truth as a scenario) and `truth.json`.
//! `--max-lead S` records each off-grid strike from a random time up to S before its approach
//! (every file S longer; `leads.csv` gives each one's lead-in). `--compliance X` gives every
//! stand-in a follicle X times as compliant as the nominal chain's base joint (drawn in 0.3–3,
//! or clamped, otherwise). `--dt S` records the strikes at a time step of S seconds instead of the scenario's 0.1 ms (1e-5: as a converged integration would). `--nominal-whisker` leaves the whisker and sensors as the nominal says (with `--segments 20
//! --discretisation gregory`: recordings of our own simulator, the reference to compare with).

use std::path::PathBuf;
use vibrissa_core::chain::Discretisation;
use vibrissa_infer::standin::{make, Options};
use vibrissa_io::scenario::Document;

/// The options, as `--help` prints them.
const USAGE: &str = "\
Writes a stand-in foreign whisker's labelled recordings into DIR.

usage: standin --seed N --out DIR [options]
  --nominal e2|FILE.toml  the nominal scenario the stand-in is drawn around (default e2)
  --segments N            the stand-in's chain (default 50)
  --discretisation RULE   its stiffness rule (default seed)
  --off-grid N            noisy off-grid strikes in eval/ (default 20)
  --calib-noise F         noise of the 9 labelled strikes in calib/, share of range (default 0)
  --eval-noise F          noise of the eval/ strikes, share of range (default 0.03)
  --nominal-whisker       keep the nominal whisker and sensors (our own simulator's recordings)
  --max-lead S            record each eval/ strike from up to S seconds before its approach
  --compliance X          a follicle X times as compliant as the nominal chain's base joint
  --dt S                  record at a time step of S seconds (1e-5: as a converged integration)";

fn main() {
    if let Err(e) = run() {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let (mut seed, mut out, mut nominal) = (None, None, "e2".to_string());
    let mut options = Options::default();
    while let Some(flag) = args.next() {
        let mut value = || args.next().ok_or(format!("{flag} needs a value"));
        match flag.as_str() {
            "--seed" => seed = Some(value()?.parse::<u64>()?),
            "--out" => out = Some(PathBuf::from(value()?)),
            "--nominal" => nominal = value()?,
            "--segments" => options.segments = value()?.parse()?,
            "--discretisation" => options.discretisation = Discretisation::from_name(&value()?)?,
            "--off-grid" => options.off_grid = value()?.parse()?,
            "--calib-noise" => options.calib_noise = value()?.parse()?,
            "--eval-noise" => options.eval_noise = value()?.parse()?,
            "--nominal-whisker" => options.perturb = false,
            "--max-lead" => options.max_lead = value()?.parse()?,
            "--compliance" => options.compliance = Some(value()?.parse()?),
            "--dt" => options.dt = Some(value()?.parse()?),
            "--help" | "-h" => {
                println!("{USAGE}");
                return Ok(());
            }
            _ => return Err(format!("unknown option {flag} (see --help)").into()),
        }
    }
    let seed = seed.ok_or("--seed N is required")?;
    let out = out.ok_or("--out DIR is required")?;
    let doc = Document::load(&nominal, &[])?;
    let standin = make(&doc, seed, &options)?;
    standin.write(&out, &options)?;
    for v in standin.true_values()? {
        println!("{:28} {:.6e}", v.key, v.value);
    }
    eprintln!("wrote {}", out.display());
    Ok(())
}
