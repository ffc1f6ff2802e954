//! The machine status: one line for people (the DRO with state, feed and overrides), every
//! field for JSON.

use proto::v1 as pb;
use serde_json::{Value, json};

use crate::render::{Render, block_name};

impl Render for pb::Status {
    fn json(&self) -> Value {
        status_json(self)
    }
    fn human(&self) -> String {
        status_line(self)
    }
}

fn state_name(s: i32) -> String {
    pb::MachineState::try_from(s)
        .map(|s| {
            s.as_str_name()
                .trim_start_matches("MACHINE_STATE_")
                .to_lowercase()
        })
        .unwrap_or_else(|_| "unknown".into())
}

/// One axis as the DRO shows it: `X12.500`, or `XØ25.000` on a diameter axis (docs/lathe.md).
pub fn dro(a: &pb::AxisStatus) -> String {
    if a.diameter {
        format!("{}Ø{:.3}", a.name, a.display_mm)
    } else {
        format!("{}{:.3}", a.name, a.commanded_mm)
    }
}

/// The status line of `cncctl status` (and of the `run` summary).
pub fn status_line(s: &pb::Status) -> String {
    let pos: Vec<String> = s.axes.iter().map(axis_text).collect();
    let block = block_name(s.block);
    let t = s.ticks.unwrap_or_default();
    let mut line = format!(
        "{:<9}{} block {block:<6} line {:<5} {:>5.1}%  {}  F {:.1} mm/s ovr {:.0}% spindle {:.0}% rapid {:.0}%  {}  ticks p50/p99/max {}/{}/{} us, overruns {}",
        state_name(s.state),
        if s.single_block { " [SB]" } else { "" },
        s.line,
        s.percent,
        pos.join(" "),
        s.path_velocity_mm_s,
        s.override_percent,
        s.spindle_override_percent,
        s.rapid_override_percent,
        s.modal_g_codes.join(" "),
        t.lateness_p50_us,
        t.lateness_p99_us,
        t.lateness_max_us,
        t.overruns
    );
    if s.axes.iter().any(|a| a.distance_to_go_mm != 0.0) {
        let togo: Vec<String> = s
            .axes
            .iter()
            .map(|a| format!("{}{:.3}", a.name, a.distance_to_go_mm))
            .collect();
        line.push_str(&format!("  to go {}", togo.join(" ")));
    }
    if s.waiting_for_spindle {
        line.push_str("  waiting for the spindle to reach its speed");
    }
    if s.optional_stop {
        line.push_str("  [M1 stops]");
    }
    if let Some(tc) = &s.tool_change {
        line.push_str(&tool_change_text(tc));
    } else if s.program_stop {
        line.push_str("  program stop (M0/M1): resume to continue");
    }
    match &s.block_finished {
        // A restart's approach (no block number, line 0) holds at its end like a block.
        Some(b) if b.block.is_none() && b.line == 0 => {
            line.push_str("  single block: approach done, resume for the next");
        }
        Some(b) => line.push_str(&format!(
            "  single block: {} (line {}) done, resume for the next",
            block_name(b.block),
            b.line
        )),
        None => {}
    }
    if s.block_delete {
        line.push_str("  [/ skipped]");
    }
    if let Some(n) = s.restart_block {
        line.push_str(&format!("  restart from N{n}: start --from-block {n}"));
    }
    if s.fault_path_deviation_mm > 0.0 {
        line.push_str(&format!(
            "  fault stop left the path by {:.3} mm",
            s.fault_path_deviation_mm
        ));
    }
    if !s.alarm.is_empty() {
        line.push_str(&format!("  ALARM: {}", s.alarm));
    }
    line
}

/// An axis's display position, marked when it is not homed or stands at a soft limit.
fn axis_text(a: &pb::AxisStatus) -> String {
    let unhomed = if a.homed { "" } else { "(not homed)" };
    let limit = match a.at_soft_limit {
        -1 => "(at soft min)",
        1 => "(at soft max)",
        _ => "",
    };
    format!("{}{unhomed}{limit}", dro(a))
}

/// Every status field, for `--json`.
pub fn status_json(s: &pb::Status) -> Value {
    let t = s.ticks.unwrap_or_default();
    json!({
        "state": state_name(s.state),
        "mode": pb::Mode::try_from(s.mode).map(|m| m.as_str_name()).unwrap_or("?"),
        "single_block": s.single_block,
        "block_finished": s.block_finished.as_ref().map(|b| json!({"block": b.block,
            "line": b.line, "block_index": b.block_index})),
        "program": s.program, "job": s.job, "block": s.block, "line": s.line,
        "block_index": s.block_index, "blocks_total": s.blocks_total, "percent": s.percent,
        "axes": s.axes.iter().map(|a| json!({"name": a.name, "commanded_mm": a.commanded_mm,
            "actual_mm": a.actual_mm, "following_error_mm": a.following_error_mm,
            "distance_to_go_mm": a.distance_to_go_mm,
            "soft_min_mm": a.soft_min_mm, "soft_max_mm": a.soft_max_mm,
            "homed": a.homed, "homing_required": a.homing_required,
            "diameter": a.diameter, "display_mm": a.display_mm,
            "at_soft_limit": a.at_soft_limit})).collect::<Vec<_>>(),
        "path_velocity_mm_s": s.path_velocity_mm_s,
        "feed_programmed": s.feed_programmed, "feed_mode": s.feed_mode,
        "override_percent": s.override_percent, "spindle_rpm": s.spindle_rpm,
        "spindle_override_percent": s.spindle_override_percent,
        "rapid_override_percent": s.rapid_override_percent,
        "modal_g_codes": s.modal_g_codes,
        "compensation": s.compensation.as_ref().map(|c| json!({"code": c.code, "entry": c.entry, "radius_mm": c.radius_mm})),
        "junction": pb::JunctionClass::try_from(s.junction).map(|j| j.as_str_name()).unwrap_or("?"),
        "kr": s.kr.as_ref().map(|k| json!({"cutting_speed_m_min": k.cutting_speed_m_min,
            "speed_limit_rpm": k.speed_limit_rpm, "radius_mm": k.radius_mm,
            "spindle_rpm": k.spindle_rpm, "output": k.output, "gear_max_rpm": k.gear_max_rpm})),
        "dynamic_set": s.dynamic_set,
        "waiting_for_spindle": s.waiting_for_spindle,
        "optional_stop": s.optional_stop, "program_stop": s.program_stop,
        "tool_change": s.tool_change.as_ref().map(|t| json!({"tool": t.tool,
            "radius_mm": t.radius_mm, "length_mm": t.length_mm})),
        "fault_path_deviation_mm": s.fault_path_deviation_mm,
        "block_delete": s.block_delete, "restart_block": s.restart_block,
        "ticks": {"ticks": t.ticks, "overruns": t.overruns, "lateness_p50_us": t.lateness_p50_us,
            "lateness_p99_us": t.lateness_p99_us, "lateness_max_us": t.lateness_max_us,
            "cycle_us": t.cycle_us},
        "alarm": s.alarm,
        "active_alarms": s.active_alarms.iter().map(alarm_json).collect::<Vec<_>>(),
        "finished_job": s.finished_job, "aborted_job": s.aborted_job, "sequence": s.sequence,
    })
}

pub fn alarm_json(a: &pb::Alarm) -> Value {
    json!({"id": a.id, "message": a.message, "source": a.source, "raised_unix_ms": a.raised_unix_ms})
}

/// The prompt of a manual tool change (M6) the program holds at.
fn tool_change_text(tc: &pb::ToolChange) -> String {
    if tc.tool == 0 {
        return "  tool change: take the tool out (T0), then resume".into();
    }
    let lengths: Vec<String> = tc.length_mm.iter().map(|v| format!("{v:.3}")).collect();
    format!(
        "  tool change: put in tool T{} (D{:02}: R {:.3}, lengths {}), then resume",
        tc.tool,
        tc.tool,
        tc.radius_mm,
        lengths.join(" ")
    )
}
