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
    /// Code page of program files (issue #31, docs/operator.md "Program text encoding"):
    /// `"utf-8"` (default), `"windows-1250"`, `"cp852"` or `"kamenicky"`. Applies to every
    /// door that reads a program's bytes (upload, validate, load, run, the library).
    #[serde(default)]
    pub encoding: EncodingSetting,
}

/// `[program] encoding`.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
pub enum EncodingSetting {
    #[default]
    #[serde(rename = "utf-8")]
    Utf8,
    #[serde(rename = "windows-1250")]
    Windows1250,
    #[serde(rename = "cp852")]
    Cp852,
    #[serde(rename = "kamenicky")]
    Kamenicky,
}

impl From<EncodingSetting> for kernel::program::encoding::TextEncoding {
    fn from(s: EncodingSetting) -> Self {
        use kernel::program::encoding::TextEncoding as T;
        match s {
            EncodingSetting::Utf8 => T::Utf8,
            EncodingSetting::Windows1250 => T::Windows1250,
            EncodingSetting::Cp852 => T::Cp852,
            EncodingSetting::Kamenicky => T::Kamenicky,
        }
    }
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
