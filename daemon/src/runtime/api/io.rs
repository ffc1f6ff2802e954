//! The machine's inputs and outputs over the API (docs/io.md): the list every view shows
//! (status stream, `ListIo`, `cncctl io`, the HMI), built from the configuration's names and
//! a snapshot.

use hal::io::IoPoint;
use proto::v1 as pb;

use super::super::config::{Config, InputFunction, OutputFunction};
use super::super::io_setup;
use super::super::rt::Snapshot;

/// What the list shows that the configuration fixes (names, functions, wiring, M functions),
/// built once; [`IoCatalogue::list`] adds the values of a snapshot.
#[derive(Clone, Debug, Default)]
pub struct IoCatalogue(pb::IoList);

impl IoCatalogue {
    pub fn of(config: &Config) -> IoCatalogue {
        let io = config.io();
        let map = io_setup::io_map(config);
        let inputs = io
            .inputs
            .iter()
            .enumerate()
            .map(|(k, i)| pb::IoPoint {
                name: i.name.clone(),
                function: input_function_name(i.function).into(),
                wiring: wiring(config, map.inputs.get(k), "0x60FD"),
                on: i.confirms.clone(),
                ..pb::IoPoint::default()
            })
            .collect();
        let outputs = io
            .outputs
            .iter()
            .enumerate()
            .map(|(k, o)| pb::IoPoint {
                name: o.name.clone(),
                function: output_function_name(o.function).into(),
                wiring: wiring(config, map.outputs.get(k), "0x60FE"),
                on: o.on.clone(),
                off: o.off.clone(),
                ..pb::IoPoint::default()
            })
            .collect();
        IoCatalogue(pb::IoList {
            inputs,
            outputs,
            ..pb::IoList::default()
        })
    }

    /// The list with the values of `s`.
    pub fn list(&self, s: &Snapshot, simulated: bool) -> pb::IoList {
        let st = &s.io;
        let mut l = self.0.clone();
        for (k, p) in l.inputs.iter_mut().enumerate() {
            p.value = st.inputs.get(k);
            p.waited_for = st.waiting.get(k);
            p.wait_timed_out = st.wait_timed_out.get(k);
        }
        for (k, p) in l.outputs.iter_mut().enumerate() {
            p.value = st.outputs.get(k);
            p.forced = st.forced.get(k);
        }
        l.estop_open = st.estop_open;
        l.door_open = st.door_open;
        l.limit_reached = st.limits.0 != 0;
        l.simulated = simulated;
        l
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
        InputFunction::Probe => "probe",
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

/// The text of a fault, naming the input of an input's fault (and an alarm input's message).
pub fn fault_text(config: &Config, reason: &hal::FaultReason) -> String {
    use hal::FaultReason::{EmergencyStop, InputAlarm, LimitSwitch};
    let input = match *reason {
        EmergencyStop { input } | LimitSwitch { input, .. } | InputAlarm { input } => input,
        _ => return reason.to_string(),
    };
    let io = config.io();
    let Some(inp) = io.inputs.get(usize::from(input)) else {
        return reason.to_string();
    };
    match (reason, &inp.message) {
        (InputAlarm { .. }, Some(m)) => format!("alarm input {}: {m}", inp.name),
        _ => format!("{reason} [input {}]", inp.name),
    }
}

/// The cycle start button (docs/io.md): a press seen on an idle machine starts the selected
/// program as the Start call does (a press on a held machine already resumed it in the RT
/// core). Without a program selected, or when the start is refused, the log says why.
pub fn spawn_cycle_start(state: std::sync::Weak<super::ApiState>) {
    tokio::spawn(async move {
        let mut last: Option<u32> = None;
        let mut every = tokio::time::interval(std::time::Duration::from_millis(10));
        every.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        loop {
            every.tick().await;
            let Some(st) = state.upgrade() else {
                return;
            };
            let s = st.ctl.snapshot();
            let presses = s.io.cycle_start_presses;
            let pressed = last.is_some_and(|l| l != presses);
            last = Some(presses);
            let idle = s.state == super::super::rt::MachineState::Idle;
            if pressed
                && idle
                && let Err(e) = super::machine::start_job(&st, None).await
            {
                tracing::warn!(
                    "cycle start button: the program did not start: {}",
                    e.message()
                );
            }
        }
    });
}
