//! Generative inference: a particle filter whose transition model is the whisker physics (the
//! seed paper's dynamic Bayesian network, its Fig. 5).
//!
//! Hidden state of a particle: the whisker's joint angles, rates and accelerations (a core
//! [`State`]) and the object's state: the box's near edge `d` (m), its speed `v` (m/s), the
//! height of its top face at t = 0 (its path is `y0 + v·t`; the start delay `t0` of the approach
//! follows from it) and, when asked for, its size (m) and friction coefficient. Transition:
//! physics steps of the core with seeded process noise on every segment; once a particle's box
//! has gone for good, its whisker rings on a copy of the model stepped once per sample (see
//! `FreeModel`). Observation: any set of the contract's channels `theta01`, `theta12`, `m0`,
//! `fx`, `fy` with independent Gaussian noise of a stated standard deviation per channel.
//!
//! A whisker known only roughly (`Config::alternatives`, `Config::sensor_spread`): each particle
//! also carries one of several whiskers (static, inherited through resampling) and a Gaussian
//! belief over the sensors' gains and offsets, updated exactly by every sample (see `sensors`),
//! by which its weight is the sample's density with the gains integrated out.
//!
//! Static unknowns get a Liu–West kernel move at every resampling: each resampled particle's
//! object parameters are shrunk toward the weighted mean by `a` and jittered with covariance
//! `(1 − a²)` times the weighted covariance, so the cloud's mean and spread are kept while its
//! points become distinct again. While a box may still touch its whisker, its height stays where
//! it is (the whisker state stays consistent with it): its speed moves, and its start delay
//! follows instead of moving on its own. Boxes that have not come
//! within reach yet are instead redrawn at every sample from the prior given that they have not
//! arrived ([`run`] calls it the waiting group), with early arrivals favoured and weighted back.
//! Resampling is systematic, when the effective sample size falls below a fraction of the
//! particle count. Every random number comes from a stream indexed by particle and generation,
//! so a run gives the same bits whatever the number of threads.

#[cfg(doc)]
use vibrissa_core::dynamics::State;

mod config;
mod draws;
mod filter;
pub mod gains;
pub mod islands;
mod likelihood;
mod method;
pub mod pool;
mod posterior;
pub mod recording;
mod sampling;
mod sensors;
mod transition;
mod whiskers;

pub use config::{
    chain_follows, coarse_segments, rough_segments, Config, Injection, Prior, CHAIN_TOLERANCE,
    PARAMS, PRIOR_BOUNDS, ROUGH_SEGMENTS,
};
pub use filter::{Filter, Particles};
pub use islands::{default_islands, lost_islands, run, ISLANDS};
pub use likelihood::{
    noise_from_series, observation_sigma, per_time_factor, temper_for, TransitionModel,
    FINE_TEMPER, MODEL_ERROR, TEMPERED_PERIOD, TRANSITION_MODELS, UNKNOWN_START_TEMPER,
};
pub use method::{
    alternative_whiskers, default_particles, online_particles, Pf, ALTERNATIVES, CALIBRATED_TEMPER,
    ONLINE_PARTICLES, RANDOMISED_TEMPER, SENSOR_FLOOR,
};
pub use posterior::{Observations, Posterior, SensorPosterior, TraceRow};
pub(crate) use sampling::systematic;
pub use sensors::SensorSpread;
pub use transition::map_joints;
pub(crate) use transition::JointMap;
