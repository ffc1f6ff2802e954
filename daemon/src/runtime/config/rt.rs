//! `[rt]`: the real-time thread's priority and memory locking.

use serde::Deserialize;

use super::InvalidConfig;

#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RtConfig {
    /// SCHED_FIFO priority of the real-time thread (1..99).
    #[serde(default = "default_priority")]
    pub priority: i32,
    /// Lock all memory (mlockall) so the RT thread never page-faults.
    #[serde(default = "default_true")]
    pub lock_memory: bool,
}

fn default_priority() -> i32 {
    80
}
fn default_true() -> bool {
    true
}

impl Default for RtConfig {
    fn default() -> Self {
        RtConfig {
            priority: default_priority(),
            lock_memory: true,
        }
    }
}

impl RtConfig {
    /// `rt.priority` within SCHED_FIFO's 1..99.
    pub fn validate(&self) -> Result<(), InvalidConfig> {
        if !(1..=99).contains(&self.priority) {
            return Err(InvalidConfig::BadValue {
                key: "rt.priority".into(),
                detail: format!("{} is outside 1..99", self.priority),
            });
        }
        Ok(())
    }
}
