//! The calibration's result assembled at the final solution: parameters with their errors and
//! correlations, per-channel residuals and noise, and the scenario overrides it writes.

use super::*;

/// The result at the final solution.
#[allow(clippy::too_many_arguments)]
pub(super) fn assemble(
    setup: &Setup,
    sol: &Solution,
    cov: &Covariance,
    before: &fit::Sims,
    rms_before: &[Option<f64>; CHANNELS],
    notes: &[Option<String>],
    gain_notes: &[Option<String>; CHANNELS],
    set: &Labelled,
    reference_channel: Option<usize>,
    iterations: usize,
    fits: usize,
    simulations: usize,
) -> Fit {
    let params = setup.params;
    let x = setup.full_x(&sol.z);
    let phys = params::physical(params, &x, &setup.free, setup.reference);
    let free = setup.free_indices();
    let p = free.len();

    // Whisker parameters: values, and standard errors by the delta method. Every determined
    // parameter's row of derivatives by the covariance's coordinates, for their correlations.
    let dim = cov.cov.nrows();
    let mut rows: Vec<(String, Vec<f64>)> = Vec::new();
    let mut parameters = Vec::new();
    for (i, param) in params.iter().enumerate() {
        let (value, grad) = &phys[i];
        let std_error = setup.free[i].then(|| {
            let mut var = 0.0;
            for (a, &ia) in free.iter().enumerate() {
                for (b, &ib) in free.iter().enumerate() {
                    var += grad[ia] * cov.cov[(a, b)] * grad[ib];
                }
            }
            var.max(0.0).sqrt()
        });
        if setup.free[i] {
            let mut row = vec![0.0; dim];
            for (a, &ia) in free.iter().enumerate() {
                row[a] = grad[ia];
            }
            rows.push((param.key.clone(), row));
        }
        let value = match (param.kind, setup.free[i], param.nominal) {
            (Kind::FollicleCompliance, false, None) => f64::INFINITY,
            _ => *value,
        };
        parameters.push(ParameterFit {
            key: param.key.clone(),
            unit: unit(param),
            nominal: param.nominal,
            value,
            std_error,
            determined: setup.free[i],
            note: notes[i].clone().or_else(|| {
                (param.kind == Kind::FollicleCompliance && param.nominal.is_none() && setup.free[i])
                    .then(|| "the nominal follicle is clamped; the recordings show a spring".into())
            }),
        });
    }

    // Gains and offsets.
    let gains = setup.gains();
    for &c in &setup.channels {
        let k = gains.iter().position(|&g| g == c);
        if let Some(k) = k {
            let mut row = vec![0.0; dim];
            row[p + k] = 1.0;
            rows.push((format!("sensors.{}.gain", NAMES[c]), row));
        }
        let note = if Some(c) == reference_channel {
            Some(
                "reference of the force scale, held: the recordings cannot tell a common gain \
                 of the force channels from the whisker's stiffness and mass"
                    .to_string(),
            )
        } else {
            gain_notes[c].clone()
        };
        parameters.push(ParameterFit {
            key: format!("sensors.{}.gain", NAMES[c]),
            unit: "1",
            nominal: Some(setup.nominal[c].gain),
            value: sol.resp[c].gain,
            std_error: k.map(|k| cov.cov[(p + k, p + k)].max(0.0).sqrt()),
            determined: setup.gain_free[c],
            note,
        });
    }
    for (k, &c) in setup.channels.iter().enumerate() {
        let j = p + gains.len() + k;
        let mut row = vec![0.0; dim];
        row[j] = 1.0;
        rows.push((format!("sensors.{}.offset", NAMES[c]), row));
        parameters.push(ParameterFit {
            key: format!("sensors.{}.offset", NAMES[c]),
            unit: UNITS[c],
            nominal: Some(setup.nominal[c].offset),
            value: sol.resp[c].offset,
            std_error: Some(cov.cov[(j, j)].max(0.0).sqrt()),
            determined: true,
            note: None,
        });
    }

    // Channels before and after.
    let rms_after = setup.rms(&sol.sims, &sol.resp);
    let channels = setup
        .channels
        .iter()
        .map(|&c| ChannelFit {
            name: NAMES[c],
            unit: UNITS[c],
            rms_before: rms_before[c].unwrap_or(f64::NAN),
            rms_after: rms_after[c].unwrap_or(f64::NAN),
            noise: setup.sigma[c],
        })
        .collect();

    // The recordings with both simulations, as the sensors record them.
    let record = |sims: &[Vec<f64>; CHANNELS], resp: &[Response; CHANNELS]| {
        std::array::from_fn(|c| sims[c].iter().map(|&v| resp[c].apply(v)).collect())
    };
    let runs = setup
        .runs
        .iter()
        .zip(&set.recordings)
        .enumerate()
        .map(|(r, (run, rec))| RunFit {
            file: run.file.clone(),
            labels: rec.labels.clone(),
            t: rec.t().to_vec(),
            recorded: run.y.clone(),
            nominal: record(&before[r], &setup.nominal),
            fitted: record(&sol.sims[r], &sol.resp),
        })
        .collect();

    Fit {
        overrides: overrides(setup, &phys, &sol.resp),
        parameters,
        channels,
        runs,
        iterations,
        simulations,
        fits,
        other_minima: 0,
        correlation: correlation(&rows, &cov.cov),
        left_out: Vec::new(),
        flat_in: Vec::new(),
        contact_substeps: None,
        hold_contacts: false,
    }
}

/// The correlation matrix of the quantities whose derivatives by the coordinates of `cov` are
/// `rows` (`(key, row)`): `R·cov·Rᵀ` scaled to ones on its diagonal, to six decimals. A
/// quantity without variance, or with an infinite one, is uncorrelated with the others.
pub(super) fn correlation(
    rows: &[(String, Vec<f64>)],
    cov: &nalgebra::DMatrix<f64>,
) -> Correlation {
    let n = rows.len();
    // A coordinate the recordings do not see at all has an infinite variance: the quantities
    // that load it are uncorrelated with the rest (and it is kept out of the product, where
    // 0·∞ would spoil every entry).
    let unseen: Vec<bool> = (0..cov.nrows()).map(|a| !cov[(a, a)].is_finite()).collect();
    let seen = cov.map(|v| if v.is_finite() { v } else { 0.0 });
    let loads_unseen: Vec<bool> = rows
        .iter()
        .map(|(_, row)| row.iter().zip(&unseen).any(|(&w, &u)| u && w != 0.0))
        .collect();
    let r = nalgebra::DMatrix::from_fn(n, cov.nrows(), |i, a| rows[i].1[a]);
    let c = &r * seen * r.transpose();
    let sd: Vec<f64> = (0..n)
        .map(|i| {
            if loads_unseen[i] {
                0.0
            } else {
                c[(i, i)].max(0.0).sqrt()
            }
        })
        .collect();
    let matrix = (0..n)
        .map(|i| {
            (0..n)
                .map(|j| {
                    if i == j {
                        1.0
                    } else if sd[i] > 0.0 && sd[j] > 0.0 {
                        // Symmetric to the last bit, whatever the rounding of the product.
                        let (a, b) = (i.min(j), i.max(j));
                        // Six decimals: a file that people read, precise enough for the
                        // spread of ratios of parameters correlated near 1.
                        ((c[(a, b)] / (sd[a] * sd[b])).clamp(-1.0, 1.0) * 1e6).round() / 1e6
                    } else {
                        0.0
                    }
                })
                .collect()
        })
        .collect();
    Correlation {
        keys: rows.iter().map(|(k, _)| k.clone()).collect(),
        matrix,
    }
}

/// SI unit of a whisker parameter.
pub(super) fn unit(p: &Param) -> &'static str {
    match p.kind {
        Kind::Modulus => "Pa",
        Kind::Density => "kg/m³",
        Kind::Taper => "m",
        Kind::FollicleCompliance => "N·m/rad",
        Kind::FollicleDamping => "N·m·s/rad",
        Kind::Damping if p.key.ends_with(".beta") => "s",
        Kind::Damping => "1",
        Kind::TimeOffset => "s",
    }
}

/// The overrides that write the fitted values into the nominal scenario: determined whisker
/// parameters, and every channel's gain and offset.
pub(super) fn overrides(
    setup: &Setup,
    phys: &[(f64, Vec<f64>)],
    resp: &[Response; CHANNELS],
) -> Vec<String> {
    let params = setup.params;
    let value = |kind: Kind| {
        params
            .iter()
            .position(|p| p.kind == kind)
            .map(|i| (setup.free[i], phys[i].0))
    };
    let mut out = Vec::new();
    for (i, p) in params.iter().enumerate() {
        if !setup.free[i] {
            continue;
        }
        let v = phys[i].0;
        match p.kind {
            Kind::Modulus | Kind::Density | Kind::Taper => out.push(format!("{}={v:?}", p.key)),
            Kind::FollicleCompliance => {
                let damping = value(Kind::FollicleDamping).map_or(0.0, |(_, d)| d);
                out.push(format!(
                    "whisker.follicle={{ kind = \"spring\", stiffness = {v:?}, damping = {damping:?} }}"
                ));
            }
            Kind::Damping => {
                let kind = match setup.reference.whisker.damping {
                    Damping::ModalRatio { .. } => "modal_ratio",
                    Damping::SegmentQ { .. } => "segment_q",
                    Damping::StiffnessProportional { .. } => "stiffness_proportional",
                    Damping::None => continue,
                };
                let name = p.key.rsplit('.').next().unwrap_or("ratio");
                out.push(format!(
                    "whisker.damping={{ kind = \"{kind}\", {name} = {v:?} }}"
                ));
            }
            Kind::FollicleDamping | Kind::TimeOffset => {}
        }
    }
    for &c in &setup.channels {
        out.push(format!(
            "sensors.{}={{ gain = {:?}, offset = {:?} }}",
            NAMES[c], resp[c].gain, resp[c].offset
        ));
    }
    out
}
