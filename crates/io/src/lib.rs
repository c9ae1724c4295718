//! Scenario files and time-series formats for vibrissa.
#![warn(missing_docs)]
