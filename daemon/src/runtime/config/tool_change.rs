//! `[tool_change]`: how the machine changes tools at `M6` (docs/setup.md).

use serde::Deserialize;

/// The tool change of the machine.
#[derive(Clone, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct ToolChangeSection {
    /// `"manual"` (the default and, for now, the only mode): M6 holds the program with a
    /// prompt naming the tool and its entry until the operator confirms with Cycle Start or
    /// Resume. An automatic changer (a sequence of M functions and waits) is not built: any
    /// other value is refused when the file is read.
    #[serde(default)]
    pub mode: ToolChangeMode,
}

#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum ToolChangeMode {
    #[default]
    Manual,
}
