//! The machine's inputs and outputs as the parts of the daemon take them (docs/io.md): the
//! buses' wiring ([`hal::io::IoMap`]), the RT core's functions ([`IoFunctions`]), the
//! interpreter's M functions ([`MFunctions`]) and the simulated machine's switches, all from
//! one validated `[io]` section ([`Config::io`]).

use hal::io::{IoBits, IoMap, IoPoint};
use kernel::outputs::{MFunction, MFunctions};
use kernel::units::TS_S;

use super::config::{
    AlarmSeverity, Config, InputConfig, InputFunction, IoSection, OutputConfig, OutputFunction,
    ToolChangeMode, parse_m,
};
use super::rt_core::{IoFunctions, MAX_STEPS, ToolChanger};

/// Where each point is wired, in the configuration's order (validated already).
pub fn io_map(config: &Config) -> IoMap {
    let io = config.io();
    let point = |node: Option<u8>, drive: Option<&str>, bit: Option<u8>| -> IoPoint {
        match (node, drive) {
            (Some(node), _) => IoPoint::Module {
                node,
                bit: bit.unwrap_or(0),
            },
            (None, Some(d)) => IoPoint::Drive {
                axis: drive_axis(config, d),
                bit: bit.unwrap_or(0),
            },
            (None, None) => match config.bus {
                super::config::BusConfig::Serial(_) => IoPoint::Serial {
                    bit: bit.unwrap_or(0),
                },
                _ => IoPoint::Sim,
            },
        }
    };
    let mut safe = IoBits::NONE;
    for (k, o) in io.outputs.iter().enumerate() {
        safe.set(k, o.safe == 1);
    }
    IoMap {
        inputs: io
            .inputs
            .iter()
            .map(|i| point(i.node_id, i.drive.as_deref(), i.bit))
            .collect(),
        outputs: io
            .outputs
            .iter()
            .map(|o| point(o.node_id, o.drive.as_deref(), o.bit))
            .collect(),
        safe_outputs: safe,
    }
}

fn drive_axis(config: &Config, drive: &str) -> u8 {
    if drive.eq_ignore_ascii_case("spindle") {
        return hal::SPINDLE_AXIS;
    }
    config
        .axes
        .iter()
        .position(|a| drive.starts_with(a.name))
        .unwrap_or(0) as u8
}

fn axis_index(config: &Config, inp: &InputConfig) -> Option<usize> {
    match inp.axis {
        Some(l) => config.axes.iter().position(|a| a.name == l),
        None => inp
            .drive
            .as_deref()
            .map(|d| usize::from(drive_axis(config, d))),
    }
    .filter(|&a| a < kernel::MAX_AXES)
}

fn steps(ms: u32) -> u32 {
    ((f64::from(ms) / 1000.0) / TS_S).ceil() as u32
}

/// What each input and output does in the RT core.
pub fn functions(config: &Config) -> IoFunctions {
    let io = config.io();
    let mut f = IoFunctions {
        inputs: io.inputs.len(),
        outputs: io.outputs.len(),
        ..IoFunctions::default()
    };
    for (k, inp) in io.inputs.iter().enumerate() {
        input_function(config, &mut f, k, inp);
    }
    for (k, out) in io.outputs.iter().enumerate() {
        output_function(&mut f, k, out);
    }
    f
}

/// The automatic tool changer of `[tool_change]` for the RT core (manual: no steps). Each
/// step is the M function the program's M codes use (`m_functions`), so bit k is output
/// (input) k there as here.
pub fn tool_changer(config: &Config) -> ToolChanger {
    let tc = &config.tool_change;
    let mut c = ToolChanger::default();
    if tc.mode != ToolChangeMode::Automatic {
        return c;
    }
    let m = m_functions(config);
    for (slot, &code) in c.steps.iter_mut().zip(tc.sequence.iter().take(MAX_STEPS)) {
        *slot = m.get(code).copied().unwrap_or_default();
    }
    c.len = tc.sequence.len().min(MAX_STEPS) as u8;
    let number = tc.number_output_indices(&config.io());
    for (slot, &k) in c.number_outputs.iter_mut().zip(&number) {
        *slot = k;
    }
    c.number_len = number.len().min(c.number_outputs.len()) as u8;
    c
}

/// Automatic mode with tool number outputs: how many (a program's M6 must fit in them).
pub fn tool_number_bits(config: &Config) -> Option<u8> {
    let tc = &config.tool_change;
    (tc.mode == ToolChangeMode::Automatic && !tc.tool_number_outputs.is_empty())
        .then(|| tc.tool_number_outputs.len().min(8) as u8)
}

fn input_function(config: &Config, f: &mut IoFunctions, k: usize, inp: &InputConfig) {
    let bit = 1u64 << k;
    if inp.invert {
        f.invert |= bit;
    }
    f.wait_steps[k] = steps(inp.timeout_ms);
    let axis = axis_index(config, inp);
    match inp.function {
        InputFunction::None => {}
        InputFunction::Estop => f.estop |= bit,
        InputFunction::LimitNeg => axis.into_iter().for_each(|a| f.limit_neg[a] |= bit),
        InputFunction::LimitPos => axis.into_iter().for_each(|a| f.limit_pos[a] |= bit),
        InputFunction::Home => axis.into_iter().for_each(|a| f.home[a] |= bit),
        InputFunction::FeedHold => f.feed_hold |= bit,
        InputFunction::CycleStart => f.cycle_start |= bit,
        InputFunction::Door => f.door |= bit,
        InputFunction::Alarm => match inp.severity {
            AlarmSeverity::Warning => f.alarm_warning |= bit,
            AlarmSeverity::Fault => f.alarm_fault |= bit,
        },
        InputFunction::Probe => f.probe |= bit,
    }
}

fn output_function(f: &mut IoFunctions, k: usize, out: &OutputConfig) {
    let bit = 1u64 << k;
    if out.safe == 1 {
        f.safe |= bit;
    }
    if !out.on.is_empty() || !out.off.is_empty() {
        f.program |= bit;
    }
    if let Some(ms) = out.pulse_ms {
        f.pulse_steps[k] = steps(ms).max(1);
    }
    match out.function {
        OutputFunction::None => {}
        OutputFunction::SpindleEnable => f.spindle_enable |= bit,
        OutputFunction::SpindleCw => f.spindle_cw |= bit,
        OutputFunction::SpindleCcw => f.spindle_ccw |= bit,
    }
}

/// The M functions the interpreter applies: outputs switched on, off or pulsed, inputs
/// waited for.
pub fn m_functions(config: &Config) -> MFunctions {
    section_m_functions(&config.io())
}

fn section_m_functions(io: &IoSection) -> MFunctions {
    let mut t = MFunctions::default();
    for (k, out) in io.outputs.iter().enumerate() {
        let bit = 1u64 << k;
        let pulse = out.pulse_ms.is_some();
        for code in out.on.iter().filter_map(|m| parse_m(m)) {
            t.add(MFunction {
                code,
                on: if pulse { 0 } else { bit },
                pulse: if pulse { bit } else { 0 },
                ..MFunction::default()
            });
        }
        for code in out.off.iter().filter_map(|m| parse_m(m)) {
            t.add(MFunction {
                code,
                off: bit,
                ..MFunction::default()
            });
        }
    }
    for (k, inp) in io.inputs.iter().enumerate() {
        for code in inp.confirms.iter().filter_map(|m| parse_m(m)) {
            t.add(MFunction {
                code,
                wait: 1 << k,
                ..MFunction::default()
            });
        }
    }
    t
}

/// One input of the simulated machine: its value at rest, and the switch it models on an
/// axis (at `at_mm`, reached at and beyond it on the side `side`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SimInputPlan {
    pub rest: bool,
    pub switch: Option<(usize, f64, f64)>,
    /// The probe: touches the simulated workpiece and tool setter.
    pub probe: bool,
}

/// The simulated machine's inputs: the e-stop chain and the door closed, every other input
/// off, limit and home switches where `sim_at_mm` puts them (wire values: `invert` applied).
pub fn sim_inputs(config: &Config) -> Vec<SimInputPlan> {
    let io = config.io();
    io.inputs
        .iter()
        .map(|inp| {
            let closed = matches!(inp.function, InputFunction::Estop | InputFunction::Door);
            let side = match inp.function {
                InputFunction::LimitNeg => Some(-1.0),
                InputFunction::LimitPos => Some(1.0),
                InputFunction::Home => Some(if axis_homing_direction(config, inp) < 0 {
                    -1.0
                } else {
                    1.0
                }),
                _ => None,
            };
            let switch = match (axis_index(config, inp), inp.sim_at_mm, side) {
                (Some(a), Some(at), Some(s)) => Some((a, at, s)),
                _ => None,
            };
            SimInputPlan {
                rest: closed != inp.invert,
                switch,
                probe: inp.function == InputFunction::Probe,
            }
        })
        .collect()
}

/// What the simulated probe touches: the `[sim]` workpiece, its bores and tool setter, with
/// the `[probe]` ball at the simulated tool's tip (docs/setup.md).
pub fn sim_probe(config: &Config) -> sim::probe::SimProbe {
    use sim::probe::{SimBox, SimCylinder, SimProbe};
    let s = &config.sim;
    let axis = |l: char| config.axes.iter().position(|a| a.name == l);
    let cylinder = |c: &super::config::SimCylinderConfig| SimCylinder {
        x_mm: c.x_mm,
        y_mm: c.y_mm,
        radius_mm: c.diameter_mm / 2.0,
        top_mm: c.top_mm,
    };
    SimProbe {
        axes: [axis('X'), axis('Y'), axis('Z')],
        tool_length_mm: s.tool_length_mm,
        ball_radius_mm: config.probe.ball_radius_mm,
        workpiece: Some(SimBox {
            min_mm: s.workpiece_min_mm,
            max_mm: s.workpiece_max_mm,
        }),
        bores: s.bores.iter().map(cylinder).collect(),
        setter: Some(cylinder(&s.tool_setter)),
    }
}

fn axis_homing_direction(config: &Config, inp: &InputConfig) -> i8 {
    axis_index(config, inp)
        .and_then(|a| config.axes.get(a))
        .map_or(-1, |a| a.homing_direction)
}

/// The name of each input and output, in order (for the API and the alarms).
pub fn names(config: &Config) -> (Vec<String>, Vec<String>) {
    let io = config.io();
    (
        io.inputs.iter().map(|i| i.name.clone()).collect(),
        io.outputs.iter().map(|o| o.name.clone()).collect(),
    )
}
