//! The start-up SDO plan of a node (PDO mapping, modes, timing, heartbeats, the first
//! position read) and the checks of the master's settings. A child of `master`.

use super::*;

/// One start-up configuration step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Step {
    Write {
        index: u16,
        subindex: u8,
        value: u32,
        size: u8,
    },
    /// Reads 0x6064 so the target can start at the actual position (CSP only).
    ReadPosition,
    /// Reads the modes of operation display 0x6061 until it shows this mode.
    CheckMode(u8),
}

/// `d` in ticks of `cycle`, rounded up.
pub(super) fn ticks(d: Duration, cycle: Duration) -> u64 {
    let n = d.as_nanos().div_ceil(cycle.as_nanos().max(1));
    u64::try_from(n).unwrap_or(u64::MAX)
}

/// `d` in whole ms for a 16-bit object (0x1016, 0x1017), saturated.
fn ms_u16(d: Duration) -> u16 {
    u16::try_from(d.as_millis()).unwrap_or(u16::MAX)
}

pub(super) fn startup_steps(c: &CanOpenConfig, n: &NodeConfig, mode: OpMode) -> Vec<Step> {
    let w = |index, subindex, value, size| Step::Write {
        index,
        subindex,
        value,
        size,
    };
    let mut steps: Vec<Step> = pdo::mapping_writes(n.node_id.get(), mode)
        .iter()
        .map(|&(i, s, v, z)| w(i, s, v, z))
        .collect();
    // Modes of operation: cyclic synchronous position (8) or velocity (9).
    steps.push(w(0x6060, 0, u32::from(mode.code()), 1));
    let cycle_ms = u32::try_from(c.cycle.as_millis()).unwrap_or(u32::MAX);
    let cycle_us = u32::try_from(c.cycle.as_micros()).unwrap_or(u32::MAX);
    steps.push(w(0x60C2, 1, cycle_ms.max(1), 1)); // interpolation period...
    steps.push(w(0x60C2, 2, (-3i8) as u8 as u32, 1)); // ...in 10^-3 s
    steps.push(w(0x1006, 0, cycle_us, 4)); // communication cycle period, µs
    steps.push(w(0x1017, 0, u32::from(ms_u16(c.drive_heartbeat)), 2));
    let consumer_ms = if c.master_heartbeat.is_zero() {
        0
    } else {
        ms_u16(c.drive_consumer_timeout)
    };
    steps.push(w(
        0x1016,
        1,
        (u32::from(c.master_node_id.get()) << 16) | u32::from(consumer_ms),
        4,
    ));
    if let Some(window) = n.following_window_increments {
        steps.push(w(0x6065, 0, window, 4));
    }
    if mode == OpMode::Csp {
        steps.push(Step::ReadPosition);
    }
    steps
}

/// The start-up plan of a CiA 401 I/O module: its PDOs and the error mode and values of its
/// outputs ([`cia401::module_pdo_writes`]), its heartbeat (the drives' period), and its watch
/// on the master's heartbeat with `io_consumer_timeout` (its outputs fall to their error
/// values by themselves when the master goes silent).
pub(super) fn module_steps(c: &CanOpenConfig, p: &cia401::ModulePlan) -> Vec<Step> {
    let mut steps: Vec<Step> = cia401::module_pdo_writes(p)
        .into_iter()
        .map(write_step)
        .collect();
    steps.push(write_step((
        0x1017,
        0,
        u32::from(ms_u16(c.drive_heartbeat)),
        2,
    )));
    let consumer_ms = if c.master_heartbeat.is_zero() {
        0
    } else {
        ms_u16(c.io_consumer_timeout)
    };
    let entry = (u32::from(c.master_node_id.get()) << 16) | u32::from(consumer_ms);
    steps.push(write_step((0x1016, 1, entry, 4)));
    steps
}

/// A drive's plan with its own digital I/O mapped into PDO2 ([`cia401::drive_io_writes`]),
/// before the mode of operation is set; nothing changes for a drive without points.
pub(super) fn with_drive_io(
    mut steps: Vec<Step>,
    node: u8,
    inputs: bool,
    outputs: bool,
) -> Vec<Step> {
    let at = steps
        .iter()
        .position(|s| matches!(s, Step::Write { index: 0x6060, .. }))
        .unwrap_or(steps.len());
    let io = cia401::drive_io_writes(node, inputs, outputs);
    steps.splice(at..at, io.into_iter().map(write_step));
    steps
}

fn write_step((index, subindex, value, size): cia401::Write) -> Step {
    Step::Write {
        index,
        subindex,
        value,
        size,
    }
}

pub(super) fn step_object(s: Step) -> (u16, u8) {
    match s {
        Step::Write {
            index, subindex, ..
        } => (index, subindex),
        Step::ReadPosition => (0x6064, 0),
        Step::CheckMode(_) => (0x6061, 0),
    }
}

/// Checks the settings the master cannot run with.
pub(super) fn check_config(cfg: &CanOpenConfig) -> Result<(), CanOpenError> {
    if cfg.nodes.is_empty() || cfg.nodes.len() > MAX_AXES {
        return Err(CanOpenError::DriveCount {
            count: cfg.nodes.len(),
        });
    }
    let cycle_ns = cfg.cycle.as_nanos();
    if !(1_000_000..=10_000_000).contains(&cycle_ns) || !cycle_ns.is_multiple_of(1_000_000) {
        return Err(CanOpenError::CycleTime {
            cycle_us: cfg.cycle.as_micros(),
        });
    }
    for (axis, n) in cfg.nodes.iter().enumerate() {
        if n.node_id == cfg.master_node_id {
            return Err(CanOpenError::AxisNodeIsMaster {
                axis,
                node: n.node_id,
            });
        }
        if cfg.nodes[..axis].iter().any(|m| m.node_id == n.node_id) {
            return Err(CanOpenError::NodeUsedTwice { node: n.node_id });
        }
        if !(n.increments_per_mm.is_finite() && n.increments_per_mm > 0.0) {
            return Err(CanOpenError::AxisScale { axis });
        }
        if !(n.max_velocity_mm_s.is_finite() && n.max_velocity_mm_s > 0.0) {
            return Err(CanOpenError::AxisSpeed { axis });
        }
    }
    let Some(sp) = &cfg.spindle else {
        return Ok(());
    };
    if sp.node_id == cfg.master_node_id {
        return Err(CanOpenError::SpindleNodeIsMaster { node: sp.node_id });
    }
    if cfg.nodes.iter().any(|m| m.node_id == sp.node_id) {
        return Err(CanOpenError::SpindleNodeUsed { node: sp.node_id });
    }
    if !(sp.units_per_rpm.is_finite() && sp.units_per_rpm > 0.0) {
        return Err(CanOpenError::SpindleScale);
    }
    Ok(())
}
