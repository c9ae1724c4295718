//! How finely contact is stepped where the simulator stands in for recordings it did not make.
//!
//! At the simulator's default 0.1 ms step the channels of a fast strike are off a converged
//! integration by up to 3% of their range on a uniform whisker and 9% on one tapered to half its
//! radius (`docs/contact.md`). A real whisker's recordings, or another engine's that resolves
//! contact finely, are not. Two places therefore simulate contact at [`CONTACT_STEP`] or finer
//! where the scenario file leaves `contact_substeps` to its default:
//!
//! - calibration (`crate::calibrate`), which writes the setting into the fitted file, so that
//!   every estimator trained on that file simulates as the fit did (and so does a scenario given
//!   that file's whisker, `--whisker-from`: `vibrissa_io::scenario::Document::adopt`);
//! - the discriminative methods' training runs of a whisker known only roughly
//!   ([`crate::family::Family::for_recordings`]: `estimate --randomise` on a nominal file),
//!   whose recordings come from elsewhere by definition.
//!
//! Calibration also holds contacts ([`holds_contacts`]) where the file leaves `hold_contacts` to
//! its default, and writes that into the fitted file too; the randomised training runs do not
//! (on the other engine's development set, `krr-invariant --randomise` read the distance to
//! 0.68 mm with contacts judged afresh and 0.71 mm held: no gain).
//!
//! Runs of the scenario itself (an experiment, `simulate`) keep the file's step, and so does the
//! particle filter, whose transitions are its own coarse chain: there the file's runs set only
//! the noise's scale, and resolving them moved the pooled filter's error on nine sets both ways
//! (0.37 → 0.42 mm on average) without a cause in its physics.

use crate::error::Result;
use vibrissa_io::scenario::Document;

/// Longest substep, s, at which contact is stepped for recordings made elsewhere (see
/// [`contact_resolution`]).
pub const CONTACT_STEP: f64 = 2e-5;

/// The substeps near contact with which `doc` is simulated for recordings made elsewhere,
/// where the file leaves `contact_substeps` to its default: enough that contact is stepped at
/// [`CONTACT_STEP`] or finer (5 at the default 0.1 ms step; `None` when the step is already
/// that fine, or the file names the setting, even as 1).
pub fn contact_resolution(doc: &Document) -> Result<Option<usize>> {
    if doc.names("contact_substeps") {
        return Ok(None);
    }
    let integrator = doc.loaded()?.scenario.integrator;
    let substeps = integrator.contact_substeps_within(CONTACT_STEP);
    Ok((substeps > integrator.contact_substeps).then_some(substeps))
}

/// Whether `doc` is to be simulated with held contacts (`hold_contacts = true`) for recordings
/// made elsewhere, where the file leaves `hold_contacts` to its default (false when the file
/// names it, either way). A contact judged afresh each step lapses for single steps while the
/// whisker stays pressed against a surface that turns away from it (docs/contact.md, "Held
/// contacts"); another engine's whisker does not: fitted with held contacts, the other engine's
/// development set left residuals 2.2–14 times smaller (docs/calibration.md).
pub fn holds_contacts(doc: &Document) -> Result<bool> {
    if doc.names("hold_contacts") {
        return Ok(false);
    }
    Ok(!doc.loaded()?.scenario.integrator.hold_contacts)
}
