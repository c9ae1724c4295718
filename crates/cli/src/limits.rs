//! The largest counts the command line accepts ([`vibrissa_infer::limits`]), checked as the
//! options are read, so that a count beyond what any machine can hold is refused with its limit
//! before anything is allocated.

use vibrissa_infer::limits::{MAX_ALTERNATIVES, MAX_BANK, MAX_PARTICLES, MAX_RUNS, MAX_TRAINING};

/// A count from `LEAST` to `MOST`.
fn count<const LEAST: usize, const MOST: usize>(text: &str) -> Result<usize, String> {
    let expected = format!("expected a whole number from {LEAST} to {MOST}");
    let n: usize = text.trim().parse().map_err(|_| expected.clone())?;
    if !(LEAST..=MOST).contains(&n) {
        return Err(format!("{expected} (got {n})"));
    }
    Ok(n)
}

/// Particles: 1 to [`MAX_PARTICLES`].
pub(crate) fn particles(text: &str) -> Result<usize, String> {
    count::<1, MAX_PARTICLES>(text)
}

/// Particles where 0 leaves the filter out: 0 to [`MAX_PARTICLES`].
pub(crate) fn particles_or_none(text: &str) -> Result<usize, String> {
    count::<0, MAX_PARTICLES>(text)
}

/// Islands of the particle filter: 1 to 64.
pub(crate) fn islands(text: &str) -> Result<usize, String> {
    count::<1, 64>(text)
}

/// Alternative whiskers: 0 to [`MAX_ALTERNATIVES`].
pub(crate) fn alternatives(text: &str) -> Result<usize, String> {
    count::<0, MAX_ALTERNATIVES>(text)
}

/// Training runs per class: 1 to [`MAX_TRAINING`].
pub(crate) fn training(text: &str) -> Result<usize, String> {
    count::<1, MAX_TRAINING>(text)
}

/// Evaluated runs per class: 1 to [`MAX_RUNS`].
pub(crate) fn runs(text: &str) -> Result<usize, String> {
    count::<1, MAX_RUNS>(text)
}

/// Bank runs per class: 1 to [`MAX_BANK`].
pub(crate) fn bank(text: &str) -> Result<usize, String> {
    count::<1, MAX_BANK>(text)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_are_refused_beyond_their_limits_with_the_limit_named() {
        assert_eq!(particles("4000"), Ok(4000));
        assert_eq!(particles(&MAX_PARTICLES.to_string()), Ok(MAX_PARTICLES));
        for bad in ["0", "1000001", "10000000000", "1e11", "-3", "many", ""] {
            let e = particles(bad).unwrap_err();
            assert!(e.contains("1 to 1000000"), "{bad}: {e}");
        }
        assert_eq!(particles_or_none("0"), Ok(0));
        assert!(alternatives("65535").unwrap_err().contains("0 to 65534"));
        assert_eq!(training("800"), Ok(800));
        assert!(training("100000000000").unwrap_err().contains("20000"));
        assert!(runs("0").is_err());
        assert!(bank("100001").unwrap_err().contains("100000"));
    }
}
