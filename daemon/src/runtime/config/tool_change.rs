//! `[tool_change]`: how the machine changes tools at `M6` (docs/setup.md).

use serde::Deserialize;

use super::InvalidConfig;
use super::io::{IoSection, parse_m};

/// The tool change of the machine.
#[derive(Clone, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct ToolChangeSection {
    /// `"manual"` (the default): M6 holds the program with a prompt naming the tool and its
    /// entry until the operator confirms with Cycle Start or Resume. `"automatic"`: at M6 the
    /// RT core runs `sequence` at rest, then the program goes on by itself.
    #[serde(default)]
    pub mode: ToolChangeMode,
    /// Automatic mode: the M codes run in order at each M6 (numbers, `61` for M61); each must
    /// be bound by `[[io.outputs]] on/off` or `[[io.inputs]] confirms`.
    #[serde(default)]
    pub sequence: Vec<u16>,
    /// Automatic mode: names of `[[io.outputs]]` that carry the tool number in binary, bit 0
    /// first, switched before the first step.
    #[serde(default)]
    pub tool_number_outputs: Vec<String>,
}

#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum ToolChangeMode {
    #[default]
    Manual,
    Automatic,
}

impl ToolChangeSection {
    /// Automatic mode: a sequence of M functions the machine's I/O binds, known output
    /// names; manual mode: neither key.
    pub fn validate(&self, io: &IoSection) -> Result<(), InvalidConfig> {
        if self.mode == ToolChangeMode::Manual {
            for (key, given) in [
                ("tool_change.sequence", !self.sequence.is_empty()),
                (
                    "tool_change.tool_number_outputs",
                    !self.tool_number_outputs.is_empty(),
                ),
            ] {
                if given {
                    return Err(bad(key, "only for mode = \"automatic\"".into()));
                }
            }
            return Ok(());
        }
        if self.sequence.is_empty() {
            return Err(InvalidConfig::Missing {
                key: "tool_change.sequence".into(),
                detail: "mode = \"automatic\" needs the M functions of the change, e.g. \
                         [61, 62, 63]"
                    .into(),
            });
        }
        if self.sequence.len() > crate::runtime::rt_core::MAX_STEPS {
            return Err(bad(
                "tool_change.sequence",
                format!(
                    "at most {} steps (the RT core's fixed table)",
                    crate::runtime::rt_core::MAX_STEPS
                ),
            ));
        }
        for (i, &code) in self.sequence.iter().enumerate() {
            if code == 6 || !bound(io, code) {
                return Err(bad(
                    &format!("tool_change.sequence[{i}]"),
                    format!(
                        "M{code} is not an M function of [[io.outputs]] on/off or \
                         [[io.inputs]] confirms"
                    ),
                ));
            }
        }
        self.check_number_outputs(io)?;
        Ok(())
    }

    fn check_number_outputs(&self, io: &IoSection) -> Result<(), InvalidConfig> {
        if self.tool_number_outputs.len() > 8 {
            return Err(bad(
                "tool_change.tool_number_outputs",
                "at most 8 (tools 0 to 255)".into(),
            ));
        }
        for (i, name) in self.tool_number_outputs.iter().enumerate() {
            let key = format!("tool_change.tool_number_outputs[{i}]");
            if !io.outputs.iter().any(|o| &o.name == name) {
                return Err(bad(&key, format!("no [[io.outputs]] is named '{name}'")));
            }
            if self.tool_number_outputs[..i].contains(name) {
                return Err(InvalidConfig::Duplicate {
                    key,
                    detail: format!("'{name}' is given twice"),
                });
            }
        }
        Ok(())
    }

    /// The indices (in `[[io.outputs]]`) of the tool-number outputs.
    pub fn number_output_indices(&self, io: &IoSection) -> Vec<u8> {
        self.tool_number_outputs
            .iter()
            .filter_map(|n| io.outputs.iter().position(|o| &o.name == n))
            .map(|k| k as u8)
            .collect()
    }
}

/// Whether an output or input of `io` binds M `code`.
fn bound(io: &IoSection, code: u16) -> bool {
    let has = |list: &[String]| list.iter().any(|m| parse_m(m) == Some(code));
    io.outputs.iter().any(|o| has(&o.on) || has(&o.off))
        || io.inputs.iter().any(|i| has(&i.confirms))
}

fn bad(key: &str, detail: String) -> InvalidConfig {
    InvalidConfig::BadValue {
        key: key.into(),
        detail,
    }
}

#[cfg(test)]
mod tests {
    use super::super::Config;
    use std::path::Path;

    const IO: &str = "[[io.outputs]]\nname = 'unclamp'\non = ['M61']\noff = ['M63']\n\
                      [[io.outputs]]\nname = 'tool_bit0'\n\
                      [[io.inputs]]\nname = 'unclamped'\nconfirms = ['M62']\n";

    /// (code, key) of the refusal of `tool_change` over `IO`, or `None` when accepted.
    fn refusal(tool_change: &str) -> Option<(&'static str, String)> {
        let text = format!("{IO}[tool_change]\n{tool_change}");
        match Config::parse(&text, Path::new("t.toml")) {
            Ok(_) => None,
            Err(super::super::ConfigError::Invalid { source, .. }) => {
                Some((source.code(), source.key().to_string()))
            }
            Err(e) => panic!("{e}"),
        }
    }

    #[test]
    fn automatic_mode_needs_bound_m_functions_and_known_outputs() {
        let ok = "mode = 'automatic'\nsequence = [61, 62, 63]\n\
                  tool_number_outputs = ['tool_bit0']\n";
        assert_eq!(refusal(ok), None);
        let c = Config::parse(&format!("{IO}[tool_change]\n{ok}"), Path::new("t")).unwrap();
        let changer = crate::runtime::io_setup::tool_changer(&c);
        assert_eq!((changer.len, changer.number_len), (3, 1));
        assert_eq!(changer.number_outputs[0], 1);
        assert_eq!(changer.steps[0].on, 0b1, "M61 switches output 0 on");
        assert_eq!(changer.steps[1].wait, 0b1, "M62 waits for input 0");
        assert_eq!(changer.steps[2].off, 0b1, "M63 switches output 0 off");
        assert_eq!(
            refusal("mode = 'automatic'\nsequence = [61, 62, 63, 61, 62, 63, 61, 62, 63]\n"),
            Some(("config_bad_value", "tool_change.sequence".into()))
        );
        assert_eq!(
            refusal("mode = 'automatic'\nsequence = [61, 64]\n"),
            Some(("config_bad_value", "tool_change.sequence[1]".into()))
        );
        assert_eq!(
            refusal("mode = 'automatic'\n"),
            Some(("config_missing", "tool_change.sequence".into()))
        );
        assert_eq!(
            refusal("mode = 'automatic'\nsequence = [61]\ntool_number_outputs = ['bit9']\n"),
            Some((
                "config_bad_value",
                "tool_change.tool_number_outputs[0]".into()
            ))
        );
        assert_eq!(
            refusal("sequence = [61]\n"),
            Some(("config_bad_value", "tool_change.sequence".into()))
        );
        assert_eq!(refusal(""), None, "manual stays the default");
    }
}
