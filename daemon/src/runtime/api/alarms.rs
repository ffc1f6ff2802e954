//! Alarm history for `StreamAlarms` and `Status.active_alarms`: a watcher task turns drive
//! faults and planning failures into raise/clear events (outside the RT thread).

use std::collections::VecDeque;
use std::sync::{Arc, Mutex};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use proto::v1 as pb;
use tokio::sync::broadcast;

use crate::runtime::controller::Controller;

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
            }),
            tx,
        }
    }

    fn push(&self, log: &mut Log, e: pb::AlarmEvent) {
        if log.history.len() >= log.cap {
            log.history.pop_front();
        }
        log.history.push_back(e.clone());
        let _ = self.tx.send(e);
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
        let mut every = tokio::time::interval(WATCH_PERIOD);
        every.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        loop {
            every.tick().await;
            if Arc::strong_count(&log) == 1 {
                return; // the API state is gone
            }
            let s = ctl.snapshot();
            let fault = s
                .fault
                .map(|_| super::alarm_text(&ctl, &s).unwrap_or_default());
            if fault != last_fault {
                match &fault {
                    Some(m) => log.raise("drive", m.clone()),
                    None => log.clear("drive"),
                }
                last_fault = fault;
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
