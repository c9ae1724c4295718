//! The contract's observation channels read from a state.

use crate::dynamics::State;
use serde::Serialize;

/// Names of the channels [`Sensors`] provides, in CSV order.
pub const CHANNELS: [&str; 5] = ["theta01", "theta12", "m0", "fx", "fy"];

/// Base observations at one instant (docs/files.md).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Sensors {
    /// Angle of the first segment against the base direction, rad.
    pub theta01: f64,
    /// Angle of the second segment against the first, rad.
    pub theta12: f64,
    /// Moment the base applies to the whisker, N·m, counter-clockwise positive.
    pub m0: f64,
    /// Force the base applies to the whisker along the base direction, N.
    pub fx: f64,
    /// Force the base applies to the whisker perpendicular to the base direction, N.
    pub fy: f64,
}

impl Sensors {
    /// Reads the channels of `state` (the base reaction comes from the last step's equations of
    /// motion and is rotated into the base frame).
    pub fn read(state: &State) -> Sensors {
        let q = state.q();
        let [m0, fx, fy] = state.base_wrench;
        let (s, c) = if state.base.angle == 0.0 {
            (0.0, 1.0)
        } else {
            state.base.angle.sin_cos()
        };
        Sensors {
            theta01: q[0],
            theta12: q[1],
            m0,
            fx: c * fx + s * fy,
            fy: -s * fx + c * fy,
        }
    }

    /// The channels as an array in [`CHANNELS`] order.
    pub fn to_array(&self) -> [f64; 5] {
        [self.theta01, self.theta12, self.m0, self.fx, self.fy]
    }
}
