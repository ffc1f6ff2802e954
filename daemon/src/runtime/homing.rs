//! The reference run as the controller orders it (issue #15), shared by the controller and
//! the simulation harness so both drive the RT core the same way: which axes in which
//! order, what each axis's request is, and what is refused before homing.

use super::config::{Config, HomingMode};
use super::controller::ControlError;
use super::rt_core::{HomeRequest, Snapshot};

/// Search travel of an axis without both soft limits, mm.
const HOMING_MAX_TRAVEL_MM: f64 = 2000.0;

/// Whether axis `i` is referenced: homed since power-on, or needing no reference run.
pub fn axis_homed(config: &Config, snap: &Snapshot, i: usize) -> bool {
    config.axes[i].homing == HomingMode::None || snap.axes.homed & (1 << i) != 0
}

/// FAILED_PRECONDITION while an axis that needs a reference run has not had one; `what`
/// names the refused action.
pub fn require_homed(config: &Config, snap: &Snapshot, what: &str) -> Result<(), ControlError> {
    let missing: String = (0..config.axes.len())
        .filter(|&i| !axis_homed(config, snap, i))
        .map(|i| config.axes[i].name)
        .collect();
    if missing.is_empty() {
        return Ok(());
    }
    Err(ControlError::WrongState(format!(
        "{what} needs homed axes: home {missing} first (cncctl home)"
    )))
}

/// The index of the axis named `axis` (one letter, any case).
pub fn axis_index(config: &Config, axis: &str) -> Result<usize, ControlError> {
    let mut chars = axis.trim().chars();
    let letter = chars.next().map(|c| c.to_ascii_uppercase());
    config
        .axes
        .iter()
        .position(|a| Some(a.name) == letter && chars.next().is_none())
        .ok_or_else(|| {
            ControlError::Invalid(format!(
                "no axis {axis:?}: the machine has {}",
                config.axis_names().iter().collect::<String>()
            ))
        })
}

/// The axes named in `axes` (when empty: those with `homing = "required"`), in their
/// configured homing order.
pub fn homing_order(config: &Config, axes: &str) -> Result<Vec<usize>, ControlError> {
    let mut list: Vec<usize> = if axes.trim().is_empty() {
        (0..config.axes.len())
            .filter(|&i| config.axes[i].homing == HomingMode::Required)
            .collect()
    } else {
        let mut v = Vec::new();
        for c in axes.chars().filter(|c| !c.is_whitespace() && *c != ',') {
            let i = axis_index(config, &c.to_string())?;
            if !v.contains(&i) {
                v.push(i);
            }
        }
        v
    };
    list.sort_by_key(|&i| (config.axes[i].home_order.unwrap_or(u8::MAX), i));
    Ok(list)
}

/// The RT core's request for the reference run of axis `i` (a bus whose drives home
/// themselves uses its own settings instead of the search parameters).
pub fn home_request(config: &Config, i: usize) -> HomeRequest {
    let a = &config.axes[i];
    let travel = match (a.soft_min_mm, a.soft_max_mm) {
        (Some(lo), Some(hi)) => 1.5 * (hi - lo),
        _ => HOMING_MAX_TRAVEL_MM,
    };
    HomeRequest {
        axis: i,
        direction: f64::from(a.homing_direction),
        speed_mm_s: a.homing_speed_mm_s(),
        accel_mm_s2: a.max_accel_mm_s2,
        reference_mm: a.reference_mm,
        max_travel_mm: travel,
    }
}

/// Why the reference run of axis `i` failed, from the snapshot after it ended.
pub fn failure(config: &Config, s: &Snapshot, i: usize) -> ControlError {
    let why = match s.alarm.fault {
        Some(f) => f.reason.to_string(),
        None if s.axes.homing_failed & (1 << i) != 0 => "home switch not found, or stopped".into(),
        None => "the machine was not idle".into(),
    };
    ControlError::Aborted(format!("homing of {} failed: {why}", config.axes[i].name))
}
