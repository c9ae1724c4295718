//! The whisker parameters a calibration fits, how each is parametrised, and how a set of values
//! turns a recording's scenario into the one simulated.

pub(crate) use crate::reference::Reference;
use vibrissa_core::objects::Motion;
use vibrissa_core::sim::{BaseDrive, Scenario};
use vibrissa_core::whisker::{Damping, Follicle};

/// What a parameter changes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Kind {
    /// Young's modulus (the bending stiffness scale): `x = ln(E/E_nominal)`.
    Modulus,
    /// Density (the linear density scale): `x = ln(ρ/ρ_nominal)`.
    Density,
    /// Tip-to-base radius ratio `q` in (0, 1]: `x = ln q` (0: a uniform whisker, the upper bound).
    Taper,
    /// Follicle compliance relative to the nominal chain's base joint, `x = ln(k0/k_f)`; a
    /// clamped follicle is the limit x → −∞.
    FollicleCompliance,
    /// Follicle damping as a time constant relative to the whisker's stiffness-proportional
    /// damping: `x = ln(c_f/(k_f·β0))`.
    FollicleDamping,
    /// The whisker's damping coefficient (ζ1, Q or β): `x = ln(value/nominal)`.
    Damping,
    /// Time of the recording's first sample on the simulation's clock, s: `x = δ`.
    TimeOffset,
}

/// Log compliance of the follicle (relative to the base joint) at and below which it is clamped.
pub(super) const CLAMPED: f64 = -8.0;

/// Bounds on `x` by kind: values beyond them are simulated as the bound (the fit sees a flat
/// cost there and reports the parameter as not determined).
pub(super) fn bounds(kind: Kind) -> (f64, f64) {
    match kind {
        Kind::Modulus | Kind::Density | Kind::Damping => (-3.0, 3.0),
        Kind::Taper => (0.1f64.ln(), 0.0),
        // At the lower bound the follicle is clamped (a spring 3000 times stiffer than the base
        // joint moves it by nothing a recording resolves).
        Kind::FollicleCompliance => (CLAMPED, 6.0),
        Kind::FollicleDamping => (-8.0, 8.0),
        Kind::TimeOffset => (-f64::INFINITY, f64::INFINITY),
    }
}

/// One fitted parameter.
#[derive(Debug, Clone)]
pub(super) struct Param {
    /// What it changes.
    pub kind: Kind,
    /// The scenario key it sets in a fitted file (`time_offset` is no scenario key).
    pub key: String,
    /// Its nominal value in SI units (`None`: a clamped follicle has no stiffness).
    pub nominal: Option<f64>,
    /// `x` of the nominal scenario (`None`: the nominal is the boundary, clamped or uniform).
    pub x_nominal: Option<f64>,
    /// `x` where the fit starts (off the boundary, so that the fit can move).
    pub x_start: f64,
    /// Finite-difference step in `x`.
    pub step: f64,
}

/// The parameters to fit for `nominal` (the scenario without labels); `labels` are the label
/// keys of the recordings (a parameter they set is known, not fitted). `time_offset` is fitted
/// only when the base does not move (it is applied by moving the objects along their paths).
pub(super) fn parameters(
    nominal: &Scenario,
    reference: &Reference,
    labels: &[String],
    step: f64,
    time_step: f64,
) -> Vec<Param> {
    let w = &nominal.whisker;
    let mut out = Vec::new();
    let mut push = |kind, key: &str, nominal, x_nominal: Option<f64>, x_start, step| {
        if !labels
            .iter()
            .any(|l| l == key || key.starts_with(&format!("{l}.")))
        {
            out.push(Param {
                kind,
                key: key.to_string(),
                nominal,
                x_nominal,
                x_start,
                step,
            });
        }
    };
    push(
        Kind::Modulus,
        "whisker.youngs_modulus",
        Some(w.youngs_modulus),
        Some(0.0),
        0.0,
        step,
    );
    push(
        Kind::Density,
        "whisker.density",
        Some(w.density),
        Some(0.0),
        0.0,
        step,
    );
    // A uniform whisker starts uniform, on the bound: its derivative there is one-sided.
    let x_taper = (w.tip_radius / w.base_radius).min(1.0).ln();
    push(
        Kind::Taper,
        "whisker.tip_radius",
        Some(w.tip_radius),
        Some(x_taper),
        x_taper,
        step,
    );
    // A clamped follicle starts clamped: the lower bound of the compliance (the search for a
    // start tries springs).
    let (x_f, x_d, k_nom, c_nom) = match w.follicle {
        Follicle::Clamped => (None, None, None, None),
        Follicle::Spring { stiffness, damping } => {
            let tau = damping / stiffness;
            (
                Some((reference.k0 / stiffness).ln()),
                (tau > 0.0).then(|| (tau / reference.beta0).ln()),
                Some(stiffness),
                Some(damping),
            )
        }
    };
    push(
        Kind::FollicleCompliance,
        "whisker.follicle.stiffness",
        k_nom,
        x_f,
        x_f.unwrap_or(CLAMPED),
        step,
    );
    // (Held with a clamped nominal, the damping is k_f·β0 if the stiffness is fitted.)
    push(
        Kind::FollicleDamping,
        "whisker.follicle.damping",
        c_nom,
        x_d.or(k_nom.is_none().then_some(0.0)),
        x_d.unwrap_or(0.0),
        step,
    );
    let damping = match w.damping {
        Damping::ModalRatio { ratio } => Some(("whisker.damping.ratio", ratio)),
        Damping::SegmentQ { q } => Some(("whisker.damping.q", q)),
        Damping::StiffnessProportional { beta } => Some(("whisker.damping.beta", beta)),
        Damping::None => None,
    };
    if let Some((key, value)) = damping {
        push(Kind::Damping, key, Some(value), Some(0.0), 0.0, step);
    }
    if nominal.base == BaseDrive::Fixed {
        push(
            Kind::TimeOffset,
            "time_offset",
            Some(0.0),
            Some(0.0),
            0.0,
            time_step,
        );
    }
    out
}

/// `base` (a recording's scenario) with the parameters set: `x[i]` is parameter `i`'s value, or
/// `None` to keep the nominal (the boundary where the nominal sits on it).
pub(super) fn apply(
    base: &Scenario,
    params: &[Param],
    x: &[Option<f64>],
    reference: &Reference,
) -> Scenario {
    let mut s = base.clone();
    let w = &mut s.whisker;
    let value = |kind: Kind| {
        params
            .iter()
            .zip(x)
            .find(|(p, _)| p.kind == kind)
            .and_then(|(_, x)| *x)
            .map(|x| {
                let (lo, hi) = bounds(kind);
                x.clamp(lo, hi)
            })
    };
    if let Some(x) = value(Kind::Modulus) {
        w.youngs_modulus *= x.exp();
    }
    if let Some(x) = value(Kind::Density) {
        w.density *= x.exp();
    }
    if let Some(x) = value(Kind::Taper) {
        w.tip_radius = w.base_radius * x.exp();
    }
    if value(Kind::FollicleCompliance).is_some_and(|x| x <= CLAMPED) {
        w.follicle = Follicle::Clamped;
    } else if let Some(x) = value(Kind::FollicleCompliance) {
        let stiffness = reference.k0 * (-x).exp();
        let tau = match (value(Kind::FollicleDamping), w.follicle) {
            (Some(xd), _) => reference.beta0 * xd.exp(),
            (None, Follicle::Spring { stiffness, damping }) => damping / stiffness,
            (None, Follicle::Clamped) => reference.beta0,
        };
        w.follicle = Follicle::Spring {
            stiffness,
            damping: stiffness * tau,
        };
    } else if let (Some(xd), Follicle::Spring { stiffness, .. }) =
        (value(Kind::FollicleDamping), w.follicle)
    {
        w.follicle = Follicle::Spring {
            stiffness,
            damping: stiffness * reference.beta0 * xd.exp(),
        };
    }
    if let Some(x) = value(Kind::Damping) {
        w.damping = match w.damping {
            Damping::ModalRatio { ratio } => Damping::ModalRatio {
                ratio: (ratio * x.exp()).min(0.95),
            },
            Damping::SegmentQ { q } => Damping::SegmentQ { q: q * x.exp() },
            Damping::StiffnessProportional { beta } => Damping::StiffnessProportional {
                beta: beta * x.exp(),
            },
            Damping::None => Damping::None,
        };
    }
    if let Some(delta) = value(Kind::TimeOffset) {
        shift_objects(&mut s, delta);
    }
    s
}

/// Moves every object along its own path so that the simulation's t = 0 is the objects' time
/// `delta` (the whisker starts at rest either way).
fn shift_objects(s: &mut Scenario, delta: f64) {
    for o in &mut s.objects {
        match &mut o.motion {
            Motion::Constant {
                velocity,
                angular_velocity,
            } => {
                o.position[0] += velocity[0] * delta;
                o.position[1] += velocity[1] * delta;
                o.angle += *angular_velocity * delta;
            }
            Motion::Waypoints { points } => {
                for p in points.iter_mut() {
                    p[0] -= delta;
                }
                let pose = o.pose(0.0);
                o.position = pose.position;
                o.angle = pose.angle;
            }
        }
    }
}

/// The physical value of every parameter (SI; the time offset in s) where parameter `i` is at
/// `x[i]` (`None`: nominal), with its gradient with respect to `x` (zero where held or beyond a
/// bound), for standard errors by the delta method. The follicle damping is `k_f·β0·e^x`, so it
/// depends on the follicle's compliance too.
pub(super) fn physical(
    params: &[Param],
    x: &[Option<f64>],
    free: &[bool],
    reference: &Reference,
) -> Vec<(f64, Vec<f64>)> {
    let n = params.len();
    let w = &reference.whisker;
    let find = |kind: Kind| params.iter().position(|p| p.kind == kind);
    let clamped = |i: usize| {
        x[i].map(|x| {
            let (lo, hi) = bounds(params[i].kind);
            (x.clamp(lo, hi), free[i] && x > lo && x < hi)
        })
    };
    params
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let mut grad = vec![0.0; n];
            let Some((xi, inside)) = clamped(i) else {
                return (p.nominal.unwrap_or(0.0), grad);
            };
            let d = if inside { 1.0 } else { 0.0 };
            let value = match p.kind {
                Kind::Modulus | Kind::Density | Kind::Damping => {
                    let v = p.nominal.unwrap_or(0.0) * xi.exp();
                    grad[i] = d * v;
                    v
                }
                Kind::Taper => {
                    let q = xi.exp();
                    grad[i] = d * w.base_radius * q;
                    w.base_radius * q
                }
                Kind::FollicleCompliance => {
                    let v = reference.k0 * (-xi).exp();
                    grad[i] = -d * v;
                    v
                }
                Kind::FollicleDamping => {
                    // c_f = k_f·β0·e^x with the stiffness of the same fit (or the nominal one).
                    let (kf, dkf) = match find(Kind::FollicleCompliance)
                        .and_then(|f| clamped(f).map(|(xf, inside_f)| (f, xf, inside_f)))
                    {
                        Some((f, xf, inside_f)) => {
                            let kf = reference.k0 * (-xf).exp();
                            (kf, Some((f, if inside_f { -kf } else { 0.0 })))
                        }
                        None => match w.follicle {
                            Follicle::Spring { stiffness, .. } => (stiffness, None),
                            Follicle::Clamped => (0.0, None),
                        },
                    };
                    let v = kf * reference.beta0 * xi.exp();
                    grad[i] = d * v;
                    if let Some((f, dk)) = dkf {
                        grad[f] = dk * reference.beta0 * xi.exp();
                    }
                    v
                }
                Kind::TimeOffset => {
                    grad[i] = d;
                    xi
                }
            };
            (value, grad)
        })
        .collect()
}

/// Whether `x` sits at the bound beyond which parameter `p` has no effect.
pub(super) fn at_bound(p: &Param, x: f64) -> bool {
    let (lo, hi) = bounds(p.kind);
    // A uniform whisker (the taper's upper bound) is a value like any other.
    x <= lo + 0.5 || (p.kind != Kind::Taper && x >= hi - 0.5)
}
