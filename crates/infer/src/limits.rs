//! The largest counts the estimators accept: beyond them a request would exhaust a machine's
//! memory before it could fail any other way, so it is refused with its limit first.

use crate::error::{Error, Result};

/// Most particles of the particle filter (a few kilobytes of state each).
pub const MAX_PARTICLES: usize = 1_000_000;
/// Most alternative whiskers the filter entertains (it numbers its whiskers with 16 bits).
pub const MAX_ALTERNATIVES: usize = 65_534;
/// Most training runs per class of a shape family (each holds every whisker's series).
pub const MAX_TRAINING: usize = 20_000;
/// Most evaluated runs per class of a shape experiment.
pub const MAX_RUNS: usize = 10_000;
/// Most noise-free runs per class in `shape-bank`'s bank.
pub const MAX_BANK: usize = 100_000;

/// Checks that the count `n` of `name` lies in `least..=most`, naming both ends if not.
pub fn check_count(name: &str, n: usize, least: usize, most: usize) -> Result<()> {
    if (least..=most).contains(&n) {
        Ok(())
    } else {
        Err(Error::Setting(format!(
            "{name}: expected a whole number from {least} to {most} (got {n})"
        )))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_count_outside_its_range_is_named_with_both_ends() {
        assert!(check_count("particles", 4000, 1, MAX_PARTICLES).is_ok());
        let e = check_count("particles", 0, 1, MAX_PARTICLES).unwrap_err();
        assert!(
            e.to_string()
                .contains("particles: expected a whole number from 1 to 1000000 (got 0)"),
            "{e}"
        );
        assert!(check_count("bank", MAX_BANK + 1, 1, MAX_BANK).is_err());
    }
}
