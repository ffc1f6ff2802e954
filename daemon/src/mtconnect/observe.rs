//! What the machine's state says about each data item (docs/mtconnect.md *Device model* and
//! *Conditions*): a snapshot of the controller becomes observations, written to the buffer
//! only where a value changed (MTConnect reports changes).

use hal::{FaultReason, SPINDLE_AXIS};
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

/// The name of input `k` (messages name the switch that acted).
fn input_name(m: &DeviceModel, k: u8) -> String {
    m.io.inputs
        .get(usize::from(k))
        .cloned()
        .unwrap_or_else(|| format!("input {k}"))
}

/// The text of an open e-stop chain (the fault's, with the input that opened).
fn estop_message(m: &DeviceModel, input: u8) -> String {
    format!(
        "{} (input {})",
        FaultReason::EmergencyStop { input },
        input_name(m, input)
    )
}

/// The text of a fault of the machine's inputs, naming the input (an alarm input's own text);
/// `None` for the other faults.
fn input_fault_message(m: &DeviceModel, reason: FaultReason) -> Option<String> {
    match reason {
        FaultReason::EmergencyStop { input } => Some(estop_message(m, input)),
        FaultReason::LimitSwitch { input, .. } => {
            Some(format!("input {}: {reason}", input_name(m, input)))
        }
        FaultReason::InputAlarm { input } => Some(
            match m.io.alarms.iter().find(|a| a.input == usize::from(input)) {
                Some(a) => format!("alarm input {}: {}", a.name, a.message),
                None => reason.to_string(),
            },
        ),
        _ => None,
    }
}

/// The alarms in force per condition data item: (item, alarm).
pub fn conditions(m: &DeviceModel, v: &MachineView) -> Vec<(usize, Cond)> {
    let ids = &m.ids;
    let mut out = Vec::new();
    if let Some(c) = drive_fault(m, v) {
        out.push(c);
    }
    // The e-stop chain open is the emergency stop even while another fault is in force.
    let estop_fault = matches!(
        v.snap.alarm.fault,
        Some(f) if matches!(f.reason, FaultReason::EmergencyStop { .. })
    );
    let io = &v.snap.io;
    let open = m.io.estop & !io.inputs.0;
    if io.estop_open && !estop_fault {
        let code = FaultReason::EmergencyStop { input: 0 }.code();
        let input = open.trailing_zeros().min(63) as u8;
        out.push((ids.system, fault(code, estop_message(m, input))));
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
    axis_conditions(m, v, &mut out);
    if let Some(item) = ids.machine_alarms {
        for a in m.io.alarms.iter().filter(|a| io.alarms.get(a.input)) {
            let level = if a.fault {
                Level::Fault
            } else {
                Level::Warning
            };
            out.push((
                item,
                Cond {
                    level,
                    native_code: Some(a.name.clone()),
                    qualifier: None,
                    message: a.message.clone(),
                },
            ));
        }
    }
    out
}

/// A Fault condition with its code.
fn fault(code: &str, message: String) -> Cond {
    Cond {
        level: Level::Fault,
        native_code: Some(code.into()),
        qualifier: None,
        message,
    }
}

/// The drive or bus fault in force, on the condition of what it names: the spindle, an axis
/// (a limit switch goes to the axis's travel condition instead), the communications or the
/// system.
fn drive_fault(m: &DeviceModel, v: &MachineView) -> Option<(usize, Cond)> {
    let ids = &m.ids;
    let f = v.snap.alarm.fault?;
    let travel_of = |axis: Option<u8>| {
        axis.and_then(|a| ids.axes.get(usize::from(a)))
            .and_then(|a| a.travel)
    };
    let label = hal::fault_axis_label(f.axis, v.axis_names);
    let node = f.node.map(|n| format!("node {n}, ")).unwrap_or_default();
    let limit = matches!(f.reason, FaultReason::LimitSwitch { .. });
    let target = match f.axis {
        _ if limit && travel_of(f.axis).is_some() => return None,
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
    let text = input_fault_message(m, f.reason).unwrap_or_else(|| f.reason.to_string());
    Some((target, fault(f.reason.code(), format!("{who}{node}{text}"))))
}

/// Per axis: a failed reference run (Warning) and its travel condition.
fn axis_conditions(m: &DeviceModel, v: &MachineView, out: &mut Vec<(usize, Cond)>) {
    for (i, a) in m.ids.axes.iter().enumerate() {
        let name = v.axis_names.get(i).copied().unwrap_or('?');
        if v.snap.axes.homing_failed & (1 << i) != 0 {
            out.push((
                a.condition,
                Cond {
                    level: Level::Warning,
                    native_code: Some("homing_failed".into()),
                    qualifier: None,
                    message: format!(
                        "axis {name}: the last reference run failed; home the axis again"
                    ),
                },
            ));
        }
        if let Some(t) = a.travel
            && let Some(c) = travel(m, v, i, name)
        {
            out.push((t, c));
        }
    }
}

/// The travel condition of axis `i` (its limit switches): Fault while its limit fault is in
/// force or a switch is reached and not yet acknowledged, Warning while a switch acknowledged
/// with Reset is still reached (only a jog away from it moves), with the side as qualifier
/// (HIGH: positive).
fn travel(m: &DeviceModel, v: &MachineView, i: usize, name: char) -> Option<Cond> {
    let io = &v.snap.io;
    let (neg, pos) = m.limits.get(i).copied().unwrap_or_default();
    let reached = io.limits.0 & (neg | pos);
    let faulted = match v.snap.alarm.fault {
        Some(f) if f.axis.map(usize::from) == Some(i) => match f.reason {
            FaultReason::LimitSwitch { positive, input } => Some((positive, input)),
            _ => None,
        },
        _ => None,
    };
    let (positive, input) = faulted.or_else(|| {
        (reached != 0).then(|| {
            let k = reached.trailing_zeros() as u8;
            (pos & (1 << k) != 0, k)
        })
    })?;
    let fresh = reached & !io.limits_acknowledged.0 != 0;
    let level = if faulted.is_some() || fresh {
        Level::Fault
    } else {
        Level::Warning
    };
    let reason = FaultReason::LimitSwitch { positive, input };
    let message = match level {
        Level::Warning => format!(
            "axis {name}: limit switch {} still reached (acknowledged): only a jog away from it moves",
            input_name(m, input)
        ),
        _ => format!("axis {name}, input {}: {reason}", input_name(m, input)),
    };
    Some(Cond {
        level,
        native_code: Some(reason.code().into()),
        qualifier: Some(if positive { "HIGH" } else { "LOW" }),
        message,
    })
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
            text(if s.io.estop_open || s.state == MachineState::Fault {
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
        (
            ids.tool_number,
            s.progress
                .tool_change
                .map_or(Value::Unavailable, |t| text(&t.to_string())),
        ),
        (
            ids.message,
            s.progress.tool_change.map_or(Value::Unavailable, |t| {
                text(&format!("tool change: put in tool T{t}, then Cycle Start"))
            }),
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
    axis_values(m, v, &mut out);
    if let Some(id) = ids.door_state {
        out.push((id, text(if s.io.door_open { "OPEN" } else { "CLOSED" })));
    }
    if let Some(id) = ids.coolant {
        let on = s.io.outputs.0 & m.io.coolant != 0;
        out.push((id, text(if on { "ON" } else { "OFF" })));
    }
    if let (Some(id), Some(axis)) = (ids.cutting_speed, v.cutting_axis) {
        let r_mm = s.axes.actual[axis].abs();
        let mm_s = std::f64::consts::TAU * r_mm * s.spindle.rpm.abs() / 60.0;
        out.push((id, num(mm_s)));
    }
    out
}

/// Per axis its actual and commanded position, and the path position (X Y Z).
fn axis_values(m: &DeviceModel, v: &MachineView, out: &mut Vec<(usize, Value)>) {
    let s = v.snap;
    let mut p = [0.0; 3];
    for (i, a) in m.ids.axes.iter().enumerate() {
        out.push((a.actual, Value::Number(round6(s.axes.actual[i]))));
        out.push((a.commanded, Value::Number(round6(s.axes.commanded[i]))));
        if i < 3 {
            p[i] = round6(s.axes.actual[i]);
        }
    }
    out.push((m.ids.path_position, Value::Vector(p)));
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
            Value::Condition(c) => Some(Cond::clone(c)),
            _ => None,
        })
        .collect();
    for c in &want {
        if !active.iter().any(|a| a == *c) {
            buf.push(now_ns, item, Value::Condition(Box::new((*c).clone())));
        }
    }
    for a in &active {
        if !want.iter().any(|c| c.native_code == a.native_code) {
            buf.push(
                now_ns,
                item,
                Value::Condition(Box::new(Cond {
                    level: Level::Normal,
                    native_code: a.native_code.clone(),
                    qualifier: None,
                    message: String::new(),
                })),
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
            Value::Condition(Box::new(Cond {
                level: Level::Normal,
                native_code: None,
                qualifier: None,
                message: String::new(),
            })),
        );
    }
}
