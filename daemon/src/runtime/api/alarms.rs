//! Alarm history for `StreamAlarms` and `Status.active_alarms`: a watcher task turns drive
//! faults and planning failures into raise/clear events (outside the RT thread).
//!
//! The history is kept in the data directory (`alarms.jsonl`, one event a line with its times,
//! issue #31) and read back at start-up, so it survives a restart; the file is rewritten with
//! the last `api.alarm_history` events when it holds twice as many. Alarms active when cncd
//! stopped are history, not active, after the restart (the machine starts anew).

use std::collections::VecDeque;
use std::io::Write;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use proto::v1 as pb;
use tokio::sync::broadcast;

use crate::runtime::controller::Controller;

/// The history file in the data directory.
pub const HISTORY_FILE: &str = "alarms.jsonl";

/// How often the watcher looks at the controller.
const WATCH_PERIOD: Duration = Duration::from_millis(10);

pub struct AlarmLog {
    inner: Mutex<Log>,
    tx: broadcast::Sender<pb::AlarmEvent>,
}

struct Log {
    history: VecDeque<pb::AlarmEvent>,
    cap: usize,
    active: Vec<pb::Alarm>,
    next_id: u64,
    /// Where the history is kept, and how many lines the file holds.
    file: Option<(PathBuf, usize)>,
}

/// One event as a line of the history file.
fn event_line(e: &pb::AlarmEvent) -> String {
    let a = e.alarm.clone().unwrap_or_default();
    serde_json::json!({"id": a.id, "source": a.source, "message": a.message,
        "raised_unix_ms": a.raised_unix_ms, "active": e.active, "event_unix_ms": e.event_unix_ms})
    .to_string()
}

fn event_of_line(line: &str) -> Option<pb::AlarmEvent> {
    let v: serde_json::Value = serde_json::from_str(line).ok()?;
    Some(pb::AlarmEvent {
        alarm: Some(pb::Alarm {
            id: v["id"].as_u64()?,
            message: v["message"].as_str()?.into(),
            raised_unix_ms: v["raised_unix_ms"].as_u64().unwrap_or(0),
            source: v["source"].as_str().unwrap_or("").into(),
        }),
        active: v["active"].as_bool().unwrap_or(false),
        from_history: true,
        event_unix_ms: v["event_unix_ms"].as_u64().unwrap_or(0),
    })
}

fn now_ms() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_millis() as u64)
}

impl AlarmLog {
    pub fn new(cap: usize) -> AlarmLog {
        let (tx, _) = broadcast::channel(256);
        AlarmLog {
            inner: Mutex::new(Log {
                history: VecDeque::new(),
                cap: cap.max(1),
                active: Vec::new(),
                next_id: 1,
                file: None,
            }),
            tx,
        }
    }

    /// A log whose history is kept in `path` and read back from it (lines that do not read
    /// are skipped). Ids go on from the highest one read.
    pub fn persistent(cap: usize, path: PathBuf) -> AlarmLog {
        let log = AlarmLog::new(cap);
        {
            let mut l = log.inner.lock().unwrap();
            let text = std::fs::read_to_string(&path).unwrap_or_default();
            let lines = text.lines().count();
            for e in text.lines().filter_map(event_of_line) {
                let id = e.alarm.as_ref().map_or(0, |a| a.id);
                l.next_id = l.next_id.max(id + 1);
                if l.history.len() >= l.cap {
                    l.history.pop_front();
                }
                l.history.push_back(e);
            }
            l.file = Some((path, lines));
        }
        log
    }

    fn push(&self, log: &mut Log, e: pb::AlarmEvent) {
        if log.history.len() >= log.cap {
            log.history.pop_front();
        }
        log.history.push_back(e.clone());
        Self::keep(log, &e);
        let _ = self.tx.send(e);
    }

    /// Appends the event to the history file (alarms are rare: a small write on the API side,
    /// never on the RT thread); rewrites the file with the history when it grew to twice it.
    fn keep(log: &mut Log, e: &pb::AlarmEvent) {
        let cap = log.cap;
        let Some((path, lines)) = &mut log.file else {
            return;
        };
        let r = if *lines >= 2 * cap {
            let text: String = log.history.iter().map(|e| event_line(e) + "\n").collect();
            *lines = log.history.len();
            crate::runtime::storage::write_atomic(path, text.as_bytes())
        } else {
            *lines += 1;
            std::fs::OpenOptions::new()
                .create(true)
                .append(true)
                .open(&*path)
                .and_then(|mut f| writeln!(f, "{}", event_line(e)))
        };
        if let Err(err) = r {
            tracing::warn!("cannot keep the alarm history in {}: {err}", path.display());
        }
    }

    /// Raises an alarm from `source` (clearing that source's previous alarm first).
    pub fn raise(&self, source: &str, message: String) {
        let mut log = self.inner.lock().unwrap();
        self.clear_locked(&mut log, source);
        let alarm = pb::Alarm {
            id: log.next_id,
            message,
            raised_unix_ms: now_ms(),
            source: source.into(),
        };
        log.next_id += 1;
        log.active.push(alarm.clone());
        tracing::warn!(id = alarm.id, source, "alarm raised: {}", alarm.message);
        let e = pb::AlarmEvent {
            alarm: Some(alarm),
            active: true,
            from_history: false,
            event_unix_ms: now_ms(),
        };
        self.push(&mut log, e);
    }

    /// Clears the active alarm of `source`, if any.
    pub fn clear(&self, source: &str) {
        let mut log = self.inner.lock().unwrap();
        self.clear_locked(&mut log, source);
    }

    fn clear_locked(&self, log: &mut Log, source: &str) {
        if let Some(i) = log.active.iter().position(|a| a.source == source) {
            let alarm = log.active.remove(i);
            tracing::info!(id = alarm.id, source, "alarm cleared");
            let e = pb::AlarmEvent {
                alarm: Some(alarm),
                active: false,
                from_history: false,
                event_unix_ms: now_ms(),
            };
            self.push(log, e);
        }
    }

    /// Alarms in force.
    pub fn active(&self) -> Vec<pb::Alarm> {
        self.inner.lock().unwrap().active.clone()
    }

    /// The history (when asked) and a receiver of later events, taken atomically.
    pub fn subscribe(
        &self,
        with_history: bool,
    ) -> (Vec<pb::AlarmEvent>, broadcast::Receiver<pb::AlarmEvent>) {
        let log = self.inner.lock().unwrap();
        let history = if with_history {
            log.history
                .iter()
                .cloned()
                .map(|mut e| {
                    e.from_history = true;
                    e
                })
                .collect()
        } else {
            Vec::new()
        };
        (history, self.tx.subscribe())
    }
}

/// Watches the controller for drive faults and planning failures.
pub fn spawn_watcher(ctl: Arc<Controller>, log: Arc<AlarmLog>) {
    tokio::spawn(async move {
        let mut last_fault: Option<String> = None;
        let mut last_plan: Option<String> = None;
        let mut last_io = IoAlarms::default();
        let mut every = tokio::time::interval(WATCH_PERIOD);
        every.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        loop {
            every.tick().await;
            if Arc::strong_count(&log) == 1 {
                return; // the API state is gone
            }
            let s = ctl.snapshot();
            let fault = s
                .alarm
                .fault
                .map(|_| super::alarm_text(&ctl, &s).unwrap_or_default());
            if fault != last_fault {
                match &fault {
                    Some(m) => log.raise("drive", m.clone()),
                    None => log.clear("drive"),
                }
                last_fault = fault;
            }
            let io = IoAlarms::of(&s);
            if io != last_io {
                io_alarm_events(&ctl, &log, last_io, io);
                last_io = io;
            }
            let plan = ctl.alarm();
            if plan != last_plan {
                match &plan {
                    Some(m) => log.raise("planner", m.clone()),
                    None => log.clear("planner"),
                }
                last_plan = plan;
            }
        }
    });
}

/// The alarms of the machine's inputs: active warning inputs, and timed-out waits of M
/// functions (docs/io.md). Fault-severity inputs, the e-stop and limit switches are faults.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct IoAlarms {
    inputs: u64,
    waits: u64,
}

impl IoAlarms {
    fn of(s: &crate::runtime::rt::Snapshot) -> IoAlarms {
        IoAlarms {
            inputs: s.io.alarms.0,
            waits: s.io.wait_timed_out.0,
        }
    }
}

/// Raises and clears one alarm per input (source `input:NAME`, `wait:NAME`).
fn io_alarm_events(ctl: &Controller, log: &AlarmLog, was: IoAlarms, now: IoAlarms) {
    let io = ctl.config().io();
    for (k, inp) in io.inputs.iter().enumerate().take(hal::io::MAX_IO) {
        let bit = 1u64 << k;
        let source = format!("input:{}", inp.name);
        match (was.inputs & bit != 0, now.inputs & bit != 0) {
            (false, true) => {
                let msg = inp
                    .message
                    .clone()
                    .unwrap_or_else(|| format!("input {} active", inp.name));
                log.raise(&source, msg);
            }
            (true, false) => log.clear(&source),
            _ => {}
        }
        let source = format!("wait:{}", inp.name);
        match (was.waits & bit != 0, now.waits & bit != 0) {
            (false, true) => log.raise(
                &source,
                format!(
                    "io_wait_timeout: input {} did not confirm within {} ms; the program holds \
                     (Resume waits again)",
                    inp.name, inp.timeout_ms
                ),
            ),
            (true, false) => log.clear(&source),
            _ => {}
        }
    }
}
