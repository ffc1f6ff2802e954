//! `[io]`: the machine's digital inputs and outputs (docs/io.md): where each is wired, the
//! function it has, and the M functions that switch outputs or wait for inputs.
//!
//! ```toml
//! [[io.inputs]]
//! name = "estop"
//! node_id = 10          # a CiA 401 module on the drives' CAN bus: 0x6000 sub 1, bit 0
//! bit = 0
//! function = "estop"    # the chain is closed when the input reads 1
//! [[io.outputs]]
//! name = "coolant"
//! node_id = 10          # 0x6200 sub 1, bit 0
//! bit = 0
//! on = ["M8"]
//! off = ["M9"]
//! ```
//! Without an `[io]` section the simulated machine has its own set ([`IoSection::sim_default`]);
//! a CAN or serial machine has none.

use serde::Deserialize;

/// `[io]` section.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct IoSection {
    #[serde(default)]
    pub inputs: Vec<InputConfig>,
    #[serde(default)]
    pub outputs: Vec<OutputConfig>,
    /// CiA 401 modules whose size is known: bits beyond it are refused.
    #[serde(default)]
    pub modules: Vec<ModuleConfig>,
    /// Heartbeat consumer time set on every CiA 401 module (0x1016), ms: with no heartbeat of
    /// the controller for this long a module's outputs fall to their safe values by themselves.
    #[serde(default = "default_consumer_ms")]
    pub module_consumer_timeout_ms: u16,
}

fn default_consumer_ms() -> u16 {
    500
}

impl Default for IoSection {
    fn default() -> Self {
        IoSection {
            inputs: Vec::new(),
            outputs: Vec::new(),
            modules: Vec::new(),
            module_consumer_timeout_ms: default_consumer_ms(),
        }
    }
}

/// What an input does (besides being shown and readable in the PLC area).
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum InputFunction {
    /// Shown only (and waited for by the M functions it `confirms`).
    #[default]
    None,
    /// Part of the emergency-stop chain: reads 1 while closed; open stops the machine.
    Estop,
    /// Hardware limit switch of `axis`, negative / positive side: reads 1 when reached.
    LimitNeg,
    LimitPos,
    /// Home switch of `axis` for reference runs the controller makes: reads 1 when pressed.
    Home,
    /// Feed hold button: 1 while pressed (the press holds the program).
    FeedHold,
    /// Cycle start button: 1 while pressed (the press resumes a hold or a program stop).
    CycleStart,
    /// Door interlock: reads 1 while the door is closed; open holds the program and the
    /// spindle.
    Door,
    /// An alarm of the machine (lubrication low, air pressure): 1 while active.
    Alarm,
    /// The probe (a touch probe or a tool setter, wired in series): 1 while touching. Read
    /// by probing moves only (docs/setup.md).
    Probe,
}

/// Severity of an alarm input.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum AlarmSeverity {
    /// Shown; nothing stops.
    #[default]
    Warning,
    /// The fault stop, like a drive fault.
    Fault,
}

/// `[[io.inputs]]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct InputConfig {
    pub name: String,
    /// A CiA 401 module on the CAN bus (with `bit`).
    #[serde(default)]
    pub node_id: Option<u8>,
    /// A drive's own inputs 0x60FD: the axis letter, or "spindle" (with `bit`).
    #[serde(default)]
    pub drive: Option<String>,
    /// Bit on the module (0 = 0x6000 sub 1 bit 0, 8 = sub 2 bit 0), of 0x60FD, or of the
    /// serial unit's input word. Not used on the simulated machine.
    #[serde(default)]
    pub bit: Option<u8>,
    /// The wire reads the opposite (a normally-closed switch where the function expects 1).
    #[serde(default)]
    pub invert: bool,
    #[serde(default)]
    pub function: InputFunction,
    /// The axis of a limit or home switch (letter).
    #[serde(default)]
    pub axis: Option<char>,
    /// Alarm inputs: the text shown.
    #[serde(default)]
    pub message: Option<String>,
    #[serde(default)]
    pub severity: AlarmSeverity,
    /// M functions whose block waits for this input to read 1 before its motion.
    #[serde(default)]
    pub confirms: Vec<String>,
    /// How long such a block waits before its alarm, ms.
    #[serde(default = "default_timeout_ms")]
    pub timeout_ms: u32,
    /// Simulated machine: the switch sits at this position of `axis` (limit and home).
    #[serde(default)]
    pub sim_at_mm: Option<f64>,
}

fn default_timeout_ms() -> u32 {
    5000
}

/// What an output follows besides its M functions.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum OutputFunction {
    /// Its M functions (`on`, `off`) and forcing only.
    #[default]
    None,
    /// On while the spindle is commanded to turn (M3/M4, not after M5, a stop or a fault).
    SpindleEnable,
    /// On while it is commanded clockwise (M3) / counter-clockwise (M4).
    SpindleCw,
    SpindleCcw,
}

/// `[[io.outputs]]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct OutputConfig {
    pub name: String,
    #[serde(default)]
    pub node_id: Option<u8>,
    #[serde(default)]
    pub drive: Option<String>,
    #[serde(default)]
    pub bit: Option<u8>,
    #[serde(default)]
    pub function: OutputFunction,
    /// M functions that switch it on (before the motion of their block).
    #[serde(default)]
    pub on: Vec<String>,
    /// M functions that switch it off.
    #[serde(default)]
    pub off: Vec<String>,
    /// The `on` M functions pulse it for this long instead, ms.
    #[serde(default)]
    pub pulse_ms: Option<u32>,
    /// Its value on a fault, an e-stop, a stop of cncd, or (modules) a broken bus: 0 or 1.
    #[serde(default)]
    pub safe: u8,
}

/// `[[io.modules]]`: a CiA 401 module's size.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ModuleConfig {
    pub node_id: u8,
    #[serde(default)]
    pub input_bits: u8,
    #[serde(default)]
    pub output_bits: u8,
}

/// M functions the controller itself gives a meaning (program stops and end, spindle, end of
/// a subprogram, feed scale): no output may take them.
pub const RESERVED_M: [u16; 10] = [0, 1, 2, 3, 4, 5, 17, 30, 36, 37];

/// Where a point is, as the configuration says it (before it is checked against the bus).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Wiring {
    Module { node: u8, bit: u8 },
    Drive { axis: u8, bit: u8 },
    Serial { bit: u8 },
    Sim,
}

/// The M code of "M8" (or "m8", "M08").
pub fn parse_m(s: &str) -> Option<u16> {
    let t = s.trim();
    let digits = t.strip_prefix('M').or_else(|| t.strip_prefix('m'))?;
    if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    digits.parse().ok()
}

/// Where the simulated machine's limit switches sit beyond a soft limit, mm ("a few mm
/// outside the travel"), and from zero on an axis without one.
pub const SIM_LIMIT_BEYOND_MM: f64 = 5.0;
pub const SIM_LIMIT_UNBOUNDED_MM: f64 = sim::io::DEFAULT_LIMIT_MM;

impl IoSection {
    /// The simulated machine's own inputs and outputs (no `[io]` section): the e-stop chain,
    /// a limit switch on each side of the first three axes a few mm outside the travel, the
    /// door, the probe, the coolant (M8/M9) and the spindle enable (M3/M4/M5).
    pub fn sim_default(axes: &[super::AxisConfig]) -> IoSection {
        let input = |name: String, function: InputFunction| InputConfig {
            name,
            node_id: None,
            drive: None,
            bit: None,
            invert: false,
            function,
            axis: None,
            message: None,
            severity: AlarmSeverity::Warning,
            confirms: Vec::new(),
            timeout_ms: default_timeout_ms(),
            sim_at_mm: None,
        };
        let mut inputs = vec![input("estop".into(), InputFunction::Estop)];
        for a in axes.iter().take(3) {
            let l = a.name.to_ascii_lowercase();
            let neg = a
                .soft_min_mm
                .map_or(-SIM_LIMIT_UNBOUNDED_MM, |m| m - SIM_LIMIT_BEYOND_MM);
            let pos = a
                .soft_max_mm
                .map_or(SIM_LIMIT_UNBOUNDED_MM, |m| m + SIM_LIMIT_BEYOND_MM);
            for (side, f, at) in [
                ("neg", InputFunction::LimitNeg, neg),
                ("pos", InputFunction::LimitPos, pos),
            ] {
                inputs.push(InputConfig {
                    axis: Some(a.name),
                    sim_at_mm: Some(at),
                    ..input(format!("{l}_limit_{side}"), f)
                });
            }
        }
        inputs.push(input("door".into(), InputFunction::Door));
        inputs.push(input("probe".into(), InputFunction::Probe));
        let output =
            |name: &str, function: OutputFunction, on: &[&str], off: &[&str]| OutputConfig {
                name: name.into(),
                node_id: None,
                drive: None,
                bit: None,
                function,
                on: on.iter().map(|s| s.to_string()).collect(),
                off: off.iter().map(|s| s.to_string()).collect(),
                pulse_ms: None,
                safe: 0,
            };
        IoSection {
            inputs,
            outputs: vec![
                output("coolant", OutputFunction::None, &["M8"], &["M9"]),
                output("spindle_enable", OutputFunction::SpindleEnable, &[], &[]),
            ],
            modules: Vec::new(),
            module_consumer_timeout_ms: default_consumer_ms(),
        }
    }
}
