//! Constant cutting speed KŘR, G96/G97/G76, and feed per revolution (SPEC §5, §6). Issue #7.
//! User documentation: `docs/kr.md`; the PLC cells: `docs/plc.md`.
//!
//! - [`config`]: R67 controlling axis, R329 d3, R580 version, gear table.
//! - [`s_word`]: what G96/G97 and S mean under R329 decade 3.
//! - [`machine`]: the per-tick state machine [`Kr`] (spindle speed, output value, AKRR_ACT_*).
//! - [`per_rev`]: V = S·β, βmax = Vmax/S, Smax = Vmax/βmax.

pub mod config;
pub mod machine;
pub mod per_rev;
pub mod s_word;

pub use config::{Gear, KrConfig, KrConfigError, KrConstants, KrVersion, RadiusInput};
pub use machine::{
    ControllingAxis, Kr, KrFault, KrInput, KrOutput, Motion, ProgramSpindle, SPINDLE_OVERRIDE_PCT,
    output_value, speed_for,
};
pub use per_rev::{feed_rate_mm_min, max_feed_mm_rev, max_spindle_rpm};
pub use s_word::{CssCode, FeedBasis, SWordMode};
