//! The NC kernel of the controller: everything from part-program text to per-tick setpoints.
//!
//! This crate is **sans-IO**: it never reads a clock, spawns a thread, opens a socket or touches a
//! file. Its callers (the daemon's runtime, the preview, benches, fuzzers and tests) feed it input
//! and poll its output, which makes it deterministic and runnable in virtual time.
//!
//! Data flows in one straight line (see `ARCHITECTURE.md` in the repository):
//! program text → [`program`] (parse + interpret, SPEC §2, §5) → [`block::Block`] →
//! [`comp`] (radius compensation, SPEC §4) → [`plan`] (look-ahead, SPEC §7) →
//! [`plan::Segment`] → [`interp`] (4 ms interpolator) → axis setpoints.

pub mod block;
pub mod comp;
pub mod constants;
pub mod diag;
pub mod estop;
pub mod interp;
pub mod jog;
pub mod kr;
pub mod limits;
pub mod machine;
pub mod offsets;
pub mod outputs;
pub mod pipeline;
pub mod plan;
pub mod plc;
pub mod probe;
pub mod program;
pub mod restart;
pub mod units;

pub use diag::{DiagCode, DiagCounts, Diagnostic, Severity};
pub use units::{AxesMm, MAX_AXES, TS_S};
