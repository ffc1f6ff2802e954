//! `[program]`: how part programs are read.

use serde::Deserialize;

/// How part programs are read (SPEC §2 **decide** points that are settings).
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct ProgramSection {
    /// Arc centre words I J: `"relative"` to the arc's start point (default) or `"absolute"`
    /// program coordinates. Every path from text to motion (load, run, preview) reads it.
    #[serde(default)]
    pub ij: IjSetting,
}

/// `[program] ij`.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum IjSetting {
    #[default]
    Relative,
    Absolute,
}

impl From<IjSetting> for kernel::program::IjMode {
    fn from(s: IjSetting) -> Self {
        match s {
            IjSetting::Relative => kernel::program::IjMode::RelativeToStart,
            IjSetting::Absolute => kernel::program::IjMode::Absolute,
        }
    }
}
