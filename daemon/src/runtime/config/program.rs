//! `[program]`: how part programs are read.

use serde::Deserialize;

use super::InvalidConfig;

/// How part programs are read (SPEC §2 **decide** points that are settings).
#[derive(Clone, Debug, Deserialize, PartialEq, Eq)]
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
    /// The machine's program language (docs/language.md): `"cnc836"` (default) or `"iso"`
    /// (RS274-NGC as LinuxCNC reads it). A program named `*.ngc`, `*.tap` or `*.gcode` is
    /// ISO whatever this says; the API's `dialect` field chooses for one program.
    #[serde(default = "default_dialect")]
    pub dialect: String,
}

fn default_dialect() -> String {
    "cnc836".into()
}

impl Default for ProgramSection {
    fn default() -> Self {
        ProgramSection {
            ij: IjSetting::default(),
            encoding: EncodingSetting::default(),
            dialect: default_dialect(),
        }
    }
}

impl ProgramSection {
    /// The default dialect (checked by [`ProgramSection::validate`]).
    pub fn dialect(&self) -> kernel::program::Dialect {
        kernel::program::Dialect::from_name(&self.dialect).unwrap_or_default()
    }

    /// `[program]`: a dialect cncd knows.
    pub fn validate(&self) -> Result<(), InvalidConfig> {
        if kernel::program::Dialect::from_name(&self.dialect).is_none() {
            return Err(InvalidConfig::BadValue {
                key: "program.dialect".into(),
                detail: format!(
                    "{:?} is not a program language cncd reads: \"cnc836\" or \"iso\"",
                    self.dialect
                ),
            });
        }
        Ok(())
    }
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
