//! What the machine's state says about each data item (docs/mtconnect.md *Device model* and
//! *Conditions*): a snapshot of the controller becomes observations, written to the buffer
//! only where a value changed (MTConnect reports changes).

use hal::SPINDLE_AXIS;
use kernel::kr::KrFault;

use super::buffer::{Buffer, Cond, Level, Value};
use super::model::DeviceModel;
use crate::runtime::rt::{MachineState, Snapshot};

/// Everything one observation pass reads: the snapshot and what the daemon knows besides.
#[derive(Clone, Copy, Debug)]
pub struct MachineView<'a> {
    pub snap: &'a Snapshot,
    /// Name of the selected program.
    pub program: Option<&'a str>,
    /// Text of the block executing (its source line), when known.
    pub block: Option<&'a str>,
    /// A planning failure in force: its stable code and message.
    pub planner_alarm: Option<(&'a str, &'a str)>,
    /// Axis letters in machine order.
    pub axis_names: &'a [char],
    /// Controlling axis of constant cutting speed (R67): its machine coordinate is the
    /// cutting radius (a radius also where the axis is programmed as a diameter).
    pub cutting_axis: Option<usize>,
}

/// µm (or 0.001 % / rpm) resolution: finer digits are noise that would flood the buffer.
fn round6(v: f64) -> f64 {
    (v * 1e6).round() / 1e6
}

/// `EXECUTION` (Part 3 Streams, ExecutionEnum) of the machine state.
pub fn execution(s: &Snapshot) -> &'static str {
    match s.state {
        MachineState::Running | MachineState::Jog | MachineState::Homing => "ACTIVE",
        MachineState::Hold if s.progress.program_stop => "PROGRAM_STOPPED",
        MachineState::Hold => "FEED_HOLD",
        MachineState::Stopping => "INTERRUPTED",
        MachineState::Fault => "STOPPED",
        MachineState::Enabling | MachineState::Shutdown => "WAIT",
        MachineState::Idle if s.progress.job != 0 && s.progress.finished_job == s.progress.job => {
            "PROGRAM_COMPLETED"
        }
        MachineState::Idle if s.progress.job != 0 && s.progress.aborted_job == s.progress.job => {
            "STOPPED"
        }
        MachineState::Idle => "READY",
    }
}

/// `CONTROLLER_MODE`: jogging and homing are MANUAL, single block SEMI_AUTOMATIC.
pub fn controller_mode(s: &Snapshot) -> &'static str {
    match s.state {
        MachineState::Jog | MachineState::Homing => "MANUAL",
        _ if s.operator.single_block => "SEMI_AUTOMATIC",
        _ => "AUTOMATIC",
    }
}

/// `ROTARY_MODE` of the spindle: always SPINDLE (it is never positioned as an axis).
const SPINDLE_MODE: &str = "SPINDLE";

/// Stable code of a KŘR fault.
pub fn kr_code(k: &KrFault) -> &'static str {
    match k {
        KrFault::UnknownGear(_) => "kr_unknown_gear",
        KrFault::BadPosition => "kr_bad_position",
    }
}

/// The alarms in force per condition data item: (item, alarm).
pub fn conditions(m: &DeviceModel, v: &MachineView) -> Vec<(usize, Cond)> {
    let ids = &m.ids;
    let mut out = Vec::new();
    let fault = |code: &str, message: String| Cond {
        level: Level::Fault,
        native_code: Some(code.into()),
        message,
    };
    if let Some(f) = v.snap.alarm.fault {
        let label = hal::fault_axis_label(f.axis, v.axis_names);
        let node = f.node.map(|n| format!("node {n}, ")).unwrap_or_default();
        let target = match f.axis {
            Some(SPINDLE_AXIS) => ids.spindle.condition,
            Some(a) if usize::from(a) < ids.axes.len() => ids.axes[usize::from(a)].condition,
            _ if f.reason.is_communication() => ids.communications,
            _ => ids.system,
        };
        let who = match (f.axis, label) {
            (Some(SPINDLE_AXIS), Some(l)) => format!("{l}, "),
            (_, Some(l)) => format!("axis {l}, "),
            _ => String::new(),
        };
        out.push((
            target,
            fault(f.reason.code(), format!("{who}{node}{}", f.reason)),
        ));
    }
    if let Some(k) = &v.snap.alarm.kr_fault {
        out.push((
            ids.system,
            fault(kr_code(k), format!("constant cutting speed: {k}")),
        ));
    }
    if let Some((code, msg)) = v.planner_alarm {
        out.push((ids.motion, fault(code, msg.to_string())));
    }
    for (i, a) in ids.axes.iter().enumerate() {
        if v.snap.axes.homing_failed & (1 << i) != 0 {
            let name = v.axis_names.get(i).copied().unwrap_or('?');
            out.push((
                a.condition,
                Cond {
                    level: Level::Warning,
                    native_code: Some("homing_failed".into()),
                    message: format!(
                        "axis {name}: the last reference run failed; home the axis again"
                    ),
                },
            ));
        }
    }
    out
}

/// The value of every sample and event data item.
pub fn values(m: &DeviceModel, v: &MachineView) -> Vec<(usize, Value)> {
    let s = v.snap;
    let ids = &m.ids;
    let num = |x: f64| Value::Number(round6(x));
    let text = |t: &str| Value::Text(t.to_string());
    let available = !matches!(s.state, MachineState::Shutdown);
    let mut out = vec![
        (
            ids.availability,
            text(if available {
                "AVAILABLE"
            } else {
                "UNAVAILABLE"
            }),
        ),
        (
            ids.emergency_stop,
            text(if s.state == MachineState::Fault {
                "TRIGGERED"
            } else {
                "ARMED"
            }),
        ),
        (ids.controller_mode, text(controller_mode(s))),
        (ids.execution, text(execution(s))),
        (ids.program, v.program.map_or(Value::Unavailable, text)),
        (ids.block, v.block.map_or(Value::Unavailable, text)),
        (
            ids.line_number,
            if s.progress.line > 0 {
                num(f64::from(s.progress.line))
            } else {
                Value::Unavailable
            },
        ),
        (ids.path_feedrate, num(s.axes.path_v_mm_s)),
        (ids.feedrate_override, num(s.operator.feed_override_pct)),
        (ids.rapid_override, num(s.operator.rapid_override_pct)),
        (ids.spindle.actual, num(s.spindle.rpm)),
        (ids.spindle.commanded, num(s.spindle.kr.spindle_rpm)),
        (
            ids.spindle.override_pct,
            num(s.operator.spindle_override_pct),
        ),
        (ids.spindle.mode, text(SPINDLE_MODE)),
    ];
    let mut p = [0.0; 3];
    for (i, a) in ids.axes.iter().enumerate() {
        out.push((a.actual, num(s.axes.actual[i])));
        out.push((a.commanded, num(s.axes.commanded[i])));
        if i < 3 {
            p[i] = round6(s.axes.actual[i]);
        }
    }
    out.push((ids.path_position, Value::Vector(p)));
    if let (Some(id), Some(axis)) = (ids.cutting_speed, v.cutting_axis) {
        let r_mm = s.axes.actual[axis].abs();
        let mm_s = std::f64::consts::TAU * r_mm * s.spindle.rpm.abs() / 60.0;
        out.push((id, num(mm_s)));
    }
    out
}

/// Writes what changed since the buffer's latest state. Returns how many observations were
/// added.
pub fn update(buf: &mut Buffer, m: &DeviceModel, v: &MachineView, now_ns: u64) -> usize {
    let before = buf.next_sequence();
    for (item, value) in values(m, v) {
        let same = buf
            .latest(item)
            .last
            .as_ref()
            .is_some_and(|o| o.value == value);
        if !same {
            buf.push(now_ns, item, value);
        }
    }
    let alarms = conditions(m, v);
    for (i, d) in m.items.iter().enumerate() {
        if d.category != super::model::Category::Condition {
            continue;
        }
        update_condition(
            buf,
            i,
            alarms.iter().filter(|(it, _)| *it == i).map(|(_, c)| c),
            now_ns,
        );
    }
    (buf.next_sequence() - before) as usize
}

/// Raises the alarms of `item` that are new or changed, clears (Normal with the code) those
/// gone, and writes Normal once for an item that was never observed or was unavailable.
fn update_condition<'a>(
    buf: &mut Buffer,
    item: usize,
    want: impl Iterator<Item = &'a Cond>,
    now_ns: u64,
) {
    let want: Vec<&Cond> = want.collect();
    let active: Vec<Cond> = buf
        .latest(item)
        .active
        .iter()
        .filter_map(|o| match &o.value {
            Value::Condition(c) => Some(c.clone()),
            _ => None,
        })
        .collect();
    for c in &want {
        if !active.iter().any(|a| a == *c) {
            buf.push(now_ns, item, Value::Condition((*c).clone()));
        }
    }
    for a in &active {
        if !want.iter().any(|c| c.native_code == a.native_code) {
            buf.push(
                now_ns,
                item,
                Value::Condition(Cond {
                    level: Level::Normal,
                    native_code: a.native_code.clone(),
                    message: String::new(),
                }),
            );
        }
    }
    let normal_known = buf
        .latest(item)
        .last
        .as_ref()
        .is_some_and(|o| matches!(o.value, Value::Condition(_)));
    if want.is_empty() && !normal_known {
        buf.push(
            now_ns,
            item,
            Value::Condition(Cond {
                level: Level::Normal,
                native_code: None,
                message: String::new(),
            }),
        );
    }
}
