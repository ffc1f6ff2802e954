//! The agent's feed: a tokio task that reads the controller's status snapshots (the watch
//! channel the gRPC status uses, never the RT thread), its alarms and the offset table, and
//! writes what changed into the agent's buffer.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use tokio::sync::watch;

use crate::mtconnect::assets::Tool;
use crate::mtconnect::model::{AlarmInput, IoDesc};
use crate::mtconnect::observe::MachineView;
use crate::mtconnect::{Agent, AxisDesc, DeviceModel, MachineDesc};
use crate::runtime::config::{AlarmSeverity, Config, InputFunction, OutputConfig, parse_m};
use crate::runtime::controller::Controller;

use super::MtconnectConfig;

/// How often the offset table is compared for AssetChanged.
const TOOLS_PERIOD: Duration = Duration::from_millis(250);

/// The agent shared by the feed and the HTTP connections, and the sequence the next
/// observation will get (streams wait on it).
pub struct Shared {
    pub agent: Mutex<Agent>,
    pub next_seq: watch::Sender<u64>,
    /// Set at shutdown: open streams end.
    pub closing: watch::Sender<bool>,
    pub streams: std::sync::atomic::AtomicUsize,
    pub max_streams: usize,
}

/// Wall-clock time, ns since the Unix epoch (document timestamps).
pub fn now_ns() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64)
}

/// A new `instanceId` per agent start: the start time in µs, and never the same twice in one
/// process (tests restart the daemon within a microsecond's reach).
fn instance_id() -> u64 {
    static LAST: AtomicU64 = AtomicU64::new(0);
    let t = (now_ns() / 1000).max(1);
    let prev = LAST.fetch_max(t, Ordering::AcqRel);
    if prev >= t {
        LAST.fetch_add(1, Ordering::AcqRel) + 1
    } else {
        t
    }
}

fn host_name() -> String {
    let mut buf = [0u8; 256];
    // SAFETY: the buffer is valid for its length; gethostname NUL-terminates within it or
    // fails.
    let r = unsafe { libc::gethostname(buf.as_mut_ptr().cast(), buf.len()) };
    let end = buf.iter().position(|b| *b == 0).unwrap_or(0);
    if r != 0 || end == 0 {
        return "cncd".into();
    }
    String::from_utf8_lossy(&buf[..end]).into_owned()
}

/// The machine description of the controller's configuration.
pub fn machine_desc(ctl: &Controller, cfg: &MtconnectConfig) -> MachineDesc {
    let config = ctl.config();
    let io = config.io();
    let limits = |axis: char, f: InputFunction| -> u64 {
        io.inputs
            .iter()
            .enumerate()
            .filter(|(_, i)| {
                let on_drive = i
                    .drive
                    .as_deref()
                    .is_some_and(|d| !d.eq_ignore_ascii_case("spindle") && d.starts_with(axis));
                i.function == f && (i.axis == Some(axis) || (i.axis.is_none() && on_drive))
            })
            .fold(0, |m, (k, _)| m | 1 << k)
    };
    MachineDesc {
        name: cfg.device_name.clone(),
        uuid: cfg.device_uuid.clone(),
        axes: config
            .axes
            .iter()
            .map(|a| AxisDesc {
                name: a.name,
                rotary: a.rotary_pulses_per_rev.is_some(),
                limit_neg: limits(a.name, InputFunction::LimitNeg),
                limit_pos: limits(a.name, InputFunction::LimitPos),
            })
            .collect(),
        cutting_speed: cutting_axis(ctl).is_some(),
        io: io_desc(config),
    }
}

/// M functions that switch the coolant by convention (ISO 6983: M7 mist, M8 flood).
const COOLANT_M: [u16; 2] = [7, 8];

/// An output is the coolant's when M7 or M8 switches it on, or its name says so.
fn is_coolant(o: &OutputConfig) -> bool {
    o.on.iter()
        .filter_map(|m| parse_m(m))
        .any(|m| COOLANT_M.contains(&m))
        || o.name.to_ascii_lowercase().contains("coolant")
}

/// The inputs and outputs the agent shows, from `[io]` in force.
fn io_desc(config: &Config) -> IoDesc {
    let io = config.io();
    let mask = |bits: &mut dyn Iterator<Item = usize>| bits.fold(0u64, |m, k| m | 1 << k);
    IoDesc {
        inputs: io.inputs.iter().map(|i| i.name.clone()).collect(),
        estop: mask(
            &mut (0..io.inputs.len()).filter(|&k| io.inputs[k].function == InputFunction::Estop),
        ),
        door: io.inputs.iter().any(|i| i.function == InputFunction::Door),
        coolant: mask(&mut (0..io.outputs.len()).filter(|&k| is_coolant(&io.outputs[k]))),
        alarms: io
            .inputs
            .iter()
            .enumerate()
            .filter(|(_, i)| i.function == InputFunction::Alarm)
            .map(|(k, i)| AlarmInput {
                input: k,
                name: i.name.clone(),
                message: i
                    .message
                    .clone()
                    .unwrap_or_else(|| format!("alarm input {} active", i.name)),
                fault: i.severity == AlarmSeverity::Fault,
            })
            .collect(),
    }
}

/// The controlling axis of constant cutting speed (R67) in force.
fn cutting_axis(ctl: &Controller) -> Option<usize> {
    let letter = kernel::kr::config::controlling_axis_letter(&ctl.constants_in_force())?;
    ctl.config().axes.iter().position(|a| a.name == letter)
}

impl Shared {
    pub fn new(ctl: &Controller, cfg: &MtconnectConfig) -> Shared {
        let model = DeviceModel::new(&machine_desc(ctl, cfg));
        let agent = Agent::new(
            model,
            cfg.buffer_size,
            instance_id(),
            &host_name(),
            now_ns(),
        );
        let next = agent.next_sequence();
        Shared {
            agent: Mutex::new(agent),
            next_seq: watch::Sender::new(next),
            closing: watch::Sender::new(false),
            streams: Default::default(),
            max_streams: cfg.max_streams,
        }
    }

    pub fn agent(&self) -> std::sync::MutexGuard<'_, Agent> {
        self.agent.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// The offset table's non-zero entries as tools (lengths named by the machine's axes 1..4).
fn tools(ctl: &Controller) -> Vec<Tool> {
    let names = ctl.config().axis_names();
    ctl.offsets_memory()
        .iter_nonzero()
        .map(|(n, e)| Tool {
            entry: n,
            radius_mm: e.radius_mm,
            lengths_mm: e
                .length_mm
                .iter()
                .enumerate()
                .filter(|(_, l)| **l != 0.0)
                .map(|(i, l)| {
                    (
                        names.get(i).copied().unwrap_or(char::from(b'1' + i as u8)),
                        *l,
                    )
                })
                .collect(),
            changed_ns: 0,
        })
        .collect()
}

/// Feeds the agent until `shared.closing` is set.
pub async fn run(ctl: Arc<Controller>, shared: Arc<Shared>, period: Duration) {
    let mut rx = ctl.subscribe();
    let mut closing = shared.closing.subscribe();
    let names = ctl.config().axis_names();
    let cutting = cutting_axis(&ctl);
    let mut tools_at = tokio::time::Instant::now() - TOOLS_PERIOD;
    loop {
        let snap = *rx.borrow_and_update();
        let program = ctl.program().map(|p| p.name.clone());
        let block = (snap.progress.line > 0).then(|| match snap.progress.block_n {
            Some(n) => format!("N{n}"),
            None => format!("line {}", snap.progress.line),
        });
        let alarm = ctl.planning_alarm();
        let view = MachineView {
            snap: &snap,
            program: program.as_deref(),
            block: block.as_deref(),
            planner_alarm: alarm.as_ref().map(|(code, text)| (*code, text.as_str())),
            axis_names: &names,
            cutting_axis: cutting,
        };
        let new_tools = (tools_at.elapsed() >= TOOLS_PERIOD).then(|| tools(&ctl));
        let next = {
            let mut a = shared.agent();
            let now = now_ns();
            a.observe(&view, now);
            if let Some(t) = new_tools {
                a.set_tools(t, now);
                tools_at = tokio::time::Instant::now();
            }
            a.next_sequence()
        };
        shared
            .next_seq
            .send_if_modified(|s| std::mem::replace(s, next) != next);
        tokio::select! {
            _ = tokio::time::sleep(period) => {}
            _ = closing.wait_for(|c| *c) => return,
        }
        tokio::select! {
            r = rx.changed() => if r.is_err() { return },
            _ = tokio::time::sleep(TOOLS_PERIOD) => {}
            _ = closing.wait_for(|c| *c) => return,
        }
    }
}
