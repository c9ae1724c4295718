//! Measures of a sampled oscillation: its frequency from the zero crossings and its damping ratio
//! from the decay of its peaks.

/// Zero-crossing times of a sampled signal (linear interpolation).
fn zero_crossings(t: &[f64], y: &[f64]) -> Vec<f64> {
    let mut out = Vec::new();
    for k in 1..y.len() {
        if (y[k - 1] < 0.0) != (y[k] < 0.0) && y[k] != y[k - 1] {
            out.push(t[k - 1] + (t[k] - t[k - 1]) * y[k - 1] / (y[k - 1] - y[k]));
        }
    }
    out
}

/// Frequency (Hz) of an oscillation from a least-squares line through its zero crossings.
pub fn crossing_frequency(t: &[f64], y: &[f64]) -> Option<f64> {
    let z = zero_crossings(t, y);
    if z.len() < 4 {
        return None;
    }
    let m = z.len() as f64;
    let kbar = (m - 1.0) / 2.0;
    let zbar = z.iter().sum::<f64>() / m;
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (k, zk) in z.iter().enumerate() {
        sxy += (k as f64 - kbar) * (zk - zbar);
        sxx += (k as f64 - kbar).powi(2);
    }
    Some(1.0 / (2.0 * sxy / sxx))
}

/// Damping ratio from the decay of the half-cycle peaks of `y`, given its frequency (Hz).
pub fn decay_ratio(t: &[f64], y: &[f64], freq: f64) -> Option<f64> {
    let z = zero_crossings(t, y);
    let mut peaks = Vec::new();
    let mut k = 0;
    for w in z.windows(2) {
        let (mut best, mut at) = (0.0f64, 0.0);
        while k < t.len() && t[k] < w[1] {
            if t[k] > w[0] && y[k].abs() > best {
                best = y[k].abs();
                at = t[k];
            }
            k += 1;
        }
        if best > 0.0 {
            peaks.push((at, best.ln()));
        }
    }
    if peaks.len() < 4 {
        return None;
    }
    let m = peaks.len() as f64;
    let tb = peaks.iter().map(|p| p.0).sum::<f64>() / m;
    let lb = peaks.iter().map(|p| p.1).sum::<f64>() / m;
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (tk, lk) in &peaks {
        sxy += (tk - tb) * (lk - lb);
        sxx += (tk - tb).powi(2);
    }
    Some(-(sxy / sxx) / (2.0 * std::f64::consts::PI * freq))
}
