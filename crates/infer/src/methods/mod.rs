//! The estimators.
//!
//! | name | budget | idea |
//! |---|---|---|
//! | `template` | paper | the seed's method: Gaussian responsibilities of the templates on `theta12` |
//! | `template-interp` | paper | least-squares fit of a (bi)linear interpolation between the templates |
//! | `template-warp` | paper | the same fit with the templates aligned at landmarks of the contact |
//! | `emulator` | free | the same fit between runs on a dense grid off the evaluated points |
//! | `knn` | free | nearest neighbours among random training runs |
//! | `krr` | free | kernel ridge regression on principal components |
//! | `krr-invariant` | free | `krr` on each channel's shape and the wrench's amplitude ratios, blind to sensor gains and stiffness |
//! | `krr-local` | free | `krr` refined by a ridge regression among the runs nearest its estimate |
//! | `shift` | free | nearest neighbours on series aligned at the contact's onset |
//! | `pf` | free | particle filter with the whisker physics as its transition model ([`crate::pf`]) |

mod aligned;
mod interp;
pub(crate) mod kernel_ridge;
mod knn;
mod krr;
mod local;
mod template;
mod warp;

pub use aligned::Aligned;
pub use interp::Interp;
pub use knn::Knn;
pub use krr::Krr;
pub use local::LocalKrr;
pub use template::Template;
pub use warp::Warp;

use crate::error::{Error, Result};
use crate::method::Method;

/// Particles of `pf` when it is built by name (the experiments' tables); `vibrissa estimate
/// --method pf --particles N` sets its own.
pub const TABLE_PARTICLES: usize = 1000;

/// Names of all methods, in the order of [`all`].
pub const NAMES: [&str; 10] = [
    "template",
    "template-interp",
    "emulator",
    "knn",
    "krr",
    "shift",
    "template-warp",
    "krr-local",
    "krr-invariant",
    "pf",
];

/// One unfitted method by name.
pub fn by_name(name: &str) -> Result<Box<dyn Method>> {
    Ok(match name {
        "template" => Box::new(Template::new()),
        "template-interp" => Box::new(Interp::paper()),
        "emulator" => Box::new(Interp::free()),
        "knn" => Box::new(Knn::plain()),
        "krr" => Box::new(Krr::new()),
        "shift" => Box::new(Knn::shifted()),
        "template-warp" => Box::new(Warp::new()),
        "krr-local" => Box::new(LocalKrr::new()),
        "krr-invariant" => Box::new(Krr::invariant()),
        "pf" => Box::new(crate::pf::Pf::new(TABLE_PARTICLES)),
        _ => {
            return Err(Error::Unknown {
                what: "method",
                name: name.into(),
                choices: NAMES.join(", "),
            })
        }
    })
}

/// All methods, unfitted.
pub fn all() -> Vec<Box<dyn Method>> {
    NAMES.iter().map(|n| by_name(n).expect("listed")).collect()
}

/// One-line descriptions of the methods, by name.
pub fn describe(name: &str) -> &'static str {
    match name {
        "template" => "the seed paper's method: theta12 only, Gaussian responsibilities of the templates (width by leave-one-out), responsibility-weighted mean",
        "template-interp" => "all channels: least-squares fit of a linear (e1) or bilinear (e2) interpolation between the template series",
        "emulator" => "all channels: the same fit between simulated runs on a dense grid that avoids the evaluated points",
        "knn" => "all channels: inverse-distance-weighted nearest neighbours among random simulated runs",
        "krr" => "all channels: kernel ridge regression (RBF) on principal components of random simulated runs (some just outside the range)",
        "shift" => "all channels aligned at the contact's onset (first |theta12| above a threshold): nearest neighbours, invariant to when contact starts",
        "template-warp" => "all channels: least-squares fit of an interpolation between the templates registered at the contact's rise and first zero crossing (travel v·t interpolated), weights linear in sqrt(L - d) and quadratic in v, channels weighted by how well the interpolation predicts the templates",
        "krr-local" => "all channels: krr's estimate refined by ridge regression on principal components of the nearest runs in parameter space (speed optionally weighted down, series optionally registered to the estimated travel, repeated about the refined estimate), settings chosen on held-out training runs",
        "krr-invariant" => "all channels: kernel ridge regression on each channel divided by its own RMS (shape and timing, blind to the sensors' gains and the whisker's stiffness) and the log ratios of the wrench's amplitudes (the moment arm m0/fy), weighted as held-out training runs choose; meant for --randomise",
        "pf" => "all channels: particle filter whose transitions are the whisker physics; posterior over the object's state at the last sample",
        _ => "",
    }
}

/// Per unknown, the (raw estimate − truth, raw std) pairs of `samples`, from a method's raw fit
/// of each sample (`fit`): what its calibration scales the raw std against.
pub(crate) fn residual_pairs(
    samples: &[crate::Sample],
    unknowns: usize,
    fit: impl Fn(&crate::Sample) -> Result<(Vec<f64>, Vec<f64>)>,
) -> Result<Vec<Vec<(f64, f64)>>> {
    let mut out = vec![Vec::new(); unknowns];
    for s in samples {
        let (p, sd) = fit(s)?;
        for u in 0..unknowns {
            out[u].push((p[u] - s.params[u], sd[u]));
        }
    }
    Ok(out)
}
