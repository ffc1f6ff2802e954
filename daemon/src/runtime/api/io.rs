//! The machine's inputs and outputs over the API (docs/io.md): the list every view shows
//! (status stream, `ListIo`, `cncctl io`, the HMI), built from the configuration's names and
//! a snapshot.

use hal::io::IoPoint;
use proto::v1 as pb;

use super::super::config::{Config, InputFunction, OutputFunction};
use super::super::io_setup;
use super::super::rt::Snapshot;

/// The list of inputs and outputs with their values in `s`.
pub fn io_list(config: &Config, s: &Snapshot, simulated: bool) -> pb::IoList {
    let io = config.io();
    let map = io_setup::io_map(config);
    let st = &s.io;
    let inputs = io
        .inputs
        .iter()
        .enumerate()
        .map(|(k, i)| pb::IoPoint {
            name: i.name.clone(),
            function: input_function_name(i.function).into(),
            value: st.inputs.get(k),
            wiring: wiring(config, map.inputs.get(k), "0x60FD"),
            forced: false,
            waited_for: st.waiting.get(k),
            wait_timed_out: st.wait_timed_out.get(k),
            on: i.confirms.clone(),
            off: Vec::new(),
        })
        .collect();
    let outputs = io
        .outputs
        .iter()
        .enumerate()
        .map(|(k, o)| pb::IoPoint {
            name: o.name.clone(),
            function: output_function_name(o.function).into(),
            value: st.outputs.get(k),
            wiring: wiring(config, map.outputs.get(k), "0x60FE"),
            forced: st.forced.get(k),
            waited_for: false,
            wait_timed_out: false,
            on: o.on.clone(),
            off: o.off.clone(),
        })
        .collect();
    pb::IoList {
        inputs,
        outputs,
        estop_open: st.estop_open,
        door_open: st.door_open,
        limit_reached: st.limits.0 != 0,
        simulated,
    }
}

fn wiring(config: &Config, p: Option<&IoPoint>, object: &str) -> String {
    match p {
        Some(IoPoint::Module { node, bit }) => format!("node {node} bit {bit}"),
        Some(IoPoint::Drive { axis, bit }) => {
            let who = hal::fault_axis_label(Some(*axis), &config.axis_names()).unwrap_or_default();
            format!("drive {who} {object} bit {bit}")
        }
        Some(IoPoint::Serial { bit }) => format!("serial bit {bit}"),
        Some(IoPoint::Sim) | None => "sim".into(),
    }
}

pub fn input_function_name(f: InputFunction) -> &'static str {
    match f {
        InputFunction::None => "",
        InputFunction::Estop => "estop",
        InputFunction::LimitNeg => "limit_neg",
        InputFunction::LimitPos => "limit_pos",
        InputFunction::Home => "home",
        InputFunction::FeedHold => "feed_hold",
        InputFunction::CycleStart => "cycle_start",
        InputFunction::Door => "door",
        InputFunction::Alarm => "alarm",
    }
}

fn output_function_name(f: OutputFunction) -> &'static str {
    match f {
        OutputFunction::None => "",
        OutputFunction::SpindleEnable => "spindle_enable",
        OutputFunction::SpindleCw => "spindle_cw",
        OutputFunction::SpindleCcw => "spindle_ccw",
    }
}
