//! The KŘR state machine, stepped once per 4 ms tick by the RT thread (SPEC §6).
//!
//! Per tick: n = v / (2π·r), clamped to min(P, limit); output Ux = n/P·U (0..7FFFh); the
//! AKRR_ACT_* cells written into the [`PlcArea`]. No allocation, no IO, no panics.

use super::config::{Gear, KrConfig, KrVersion, RadiusInput};
use crate::block::{Block, Spindle, SpindleDir};
use crate::plc::{CellId, PlcArea, cntr};

/// 1/8 µm per mm (units of AKRR_DIST and AKRR_ACT_R).
const EIGHTH_UM_PER_MM: f64 = 8000.0;
/// 1/1000 rpm per rpm (units of AKRR_*SMAX, AKRR_ACT_P, AKRR_ACT_S).
const MILLI_RPM_PER_RPM: f64 = 1000.0;

/// The program's spindle state in force this tick (from the block being executed).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ProgramSpindle {
    /// M3/M4/M5.
    pub dir: SpindleDir,
    /// G96/G97 in force (G94/G95 cancel it).
    pub css: bool,
    /// The modal S word as written: rpm without KŘR, cutting speed with it (unit per R329 d3).
    /// The interpreter sets it to 0 when KŘR ends in a block without S: the speed is then the
    /// last reached one, which only this state machine knows (SPEC §6).
    pub s_word: f64,
    /// G76 limit in rpm, 0 = none.
    pub limit_rpm: f64,
    /// Gear range, 1-based; 0 = none selected yet (gear 1 is used).
    pub gear: u8,
}

impl ProgramSpindle {
    /// The spindle state of the block being executed.
    pub fn from_block(block: &Block) -> Self {
        ProgramSpindle {
            dir: block.spindle.dir,
            css: block.spindle.css,
            s_word: block.spindle.s,
            limit_rpm: block.spindle.limit_rpm,
            gear: block.spindle.gear,
        }
    }
}

/// What moves in this tick (old KŘR is computed in motion blocks only).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Motion {
    /// No motion: a technology block, a dwell, idle.
    #[default]
    Stationary,
    /// G0. The speed follows the diameter in rapids too, unless G94 cancelled G96 (SPEC §6).
    Rapid,
    /// G1/G2/G3, jogging or PLC-driven motion.
    Feed,
}

/// Commanded position of the controlling axis (R67) and the corrections in force for it, all in
/// the axis's own units (a diameter when the axis is programmed as a diameter).
///
/// The tool tip, in program coordinates, is `carriage_mm − origin_shift_mm − length_offset_mm`;
/// KŘR computes there (SPEC §6), or at the carriage when EXT_AKRR_SUPORT is set.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ControllingAxis {
    /// Commanded machine position of the axis (carriage).
    pub carriage_mm: f64,
    /// Tool length offset of the axis in force.
    pub length_offset_mm: f64,
    /// Origin shift of the axis in force.
    pub origin_shift_mm: f64,
}

impl ControllingAxis {
    /// The axis with its carriage at `carriage_mm` and the length offset and origin shift that
    /// ride with the spindle state of the block being executed (SPEC §6: offset and origin
    /// changes act at once, the speed follows the tool tip).
    pub fn of(carriage_mm: f64, spindle: &Spindle) -> Self {
        ControllingAxis {
            carriage_mm,
            length_offset_mm: spindle.length_offset_mm,
            origin_shift_mm: spindle.origin_shift_mm,
        }
    }

    /// Axis at a program position `tip_mm` with no offsets or shifts.
    pub fn at(tip_mm: f64) -> Self {
        ControllingAxis {
            carriage_mm: tip_mm,
            ..Self::default()
        }
    }
}

/// Everything one tick needs.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct KrInput {
    pub program: ProgramSpindle,
    pub motion: Motion,
    pub axis: ControllingAxis,
}

/// Why a tick could not compute a speed. The machine must be stopped by the caller.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum KrFault {
    #[error(
        "gear range {0} is not configured: the spindle speed cannot be computed, output set to 0"
    )]
    UnknownGear(u8),
    #[error("the controlling axis position is not a number: the last spindle speed is kept")]
    BadPosition,
}

/// What one tick produced.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct KrOutput {
    /// Spindle velocity setpoint for the drive, rpm: positive M3, negative M4, 0 when stopped
    /// (goes to `hal::CycleCommand::spindle_rpm`).
    pub spindle_rpm: f64,
    /// Computed speed n, rpm (AKRR_ACT_S), regardless of M3/M4/M5.
    pub speed_rpm: f64,
    /// Spindle output value Ux = n/P·U, 0..7FFFh (AKRR_ACT_OUT).
    pub output: u16,
    /// KŘR is in force this tick.
    pub active: bool,
    pub fault: Option<KrFault>,
}

/// Constant cutting speed control (KŘR).
#[derive(Clone, Debug)]
pub struct Kr {
    cfg: KrConfig,
    active: bool,
    /// Last computed speed, rpm (the "last reached speed", SPEC §6).
    speed_rpm: f64,
    /// Last reached speed, kept as S after KŘR ended, rpm.
    held_rpm: Option<f64>,
    /// Last cutting speed programmed with G96/G97, mm/min.
    program_v_mm_min: f64,
    /// Spindle override (operator, 50..120 %) as a factor on the commanded speed.
    override_factor: f64,
}

/// Spindle override range, percent (the operator's knob).
pub const SPINDLE_OVERRIDE_PCT: std::ops::RangeInclusive<f64> = 50.0..=120.0;

impl Kr {
    pub fn new(cfg: KrConfig) -> Self {
        Kr {
            cfg,
            active: false,
            speed_rpm: 0.0,
            held_rpm: None,
            program_v_mm_min: 0.0,
            override_factor: 1.0,
        }
    }

    /// Spindle override in percent, clamped to [`SPINDLE_OVERRIDE_PCT`]: scales the commanded
    /// speed from the next tick, never above the gear range's maximum P (or the G76 /
    /// AKRR_SMAX limit under KŘR). Kept across jobs and resets, like the feed override.
    pub fn set_override(&mut self, percent: f64) {
        let p = if percent.is_finite() { percent } else { 100.0 };
        let (lo, hi) = (*SPINDLE_OVERRIDE_PCT.start(), *SPINDLE_OVERRIDE_PCT.end());
        self.override_factor = p.clamp(lo, hi) / 100.0;
    }

    pub fn config(&self) -> &KrConfig {
        &self.cfg
    }

    /// A job's constants (R67, R329, R580) take effect: called when the job starts, so every
    /// stage of the job reads the same snapshot. No allocation.
    pub fn set_constants(&mut self, k: super::config::KrConstants) {
        self.cfg.set_constants(k);
    }

    /// Forgets the program's state (program reset): KŘR off, no held speed, speed 0.
    pub fn reset(&mut self) {
        self.active = false;
        self.speed_rpm = 0.0;
        self.held_rpm = None;
        self.program_v_mm_min = 0.0;
    }

    /// Last computed speed, rpm.
    pub fn speed_rpm(&self) -> f64 {
        self.speed_rpm
    }

    pub fn is_active(&self) -> bool {
        self.active
    }

    /// One tick. Call [`PlcArea::begin_tick`] before it so the PLC's writes are in force.
    pub fn tick(&mut self, input: &KrInput, plc: &mut PlcArea) -> KrOutput {
        let v2 = self.cfg.version == KrVersion::V2;
        // Old KŘR has no PLC control (SPEC §6, R580 = 00).
        let bits = if v2 { plc.cntr() } else { 0 };
        let p = input.program;
        let active = self.update_active(&p, bits & cntr::EXT_AKRR_REQ != 0);
        let Some(gear) = self.cfg.gear(p.gear).copied() else {
            return self.fault(KrFault::UnknownGear(p.gear), p.dir, plc);
        };
        let ext = self.external_inputs(v2, bits, &p, plc);
        let cap_rpm = if ext.limit_rpm > 0.0 {
            gear.max_rpm.min(ext.limit_rpm)
        } else {
            gear.max_rpm
        };
        let Some(x_mm) = controlling_x_mm(&input.axis, bits & cntr::EXT_AKRR_SUPORT != 0) else {
            return self.fault(KrFault::BadPosition, p.dir, plc);
        };
        let radius_mm =
            (self.radius_of(x_mm) + f64::from(ext.dist_raw) / EIGHTH_UM_PER_MM).max(0.0);
        let speed_rpm = if active {
            if v2 || input.motion != Motion::Stationary {
                speed_for(
                    ext.v_mm_min + f64::from(ext.vcorr_mm_min),
                    radius_mm,
                    cap_rpm,
                )
            } else {
                // Old KŘR outside motion blocks: the speed stays.
                self.speed_rpm.min(gear.max_rpm)
            }
        } else if let Some(held_rpm) = self.held_rpm {
            held_rpm.min(gear.max_rpm)
        } else {
            p.s_word.max(0.0).min(gear.max_rpm)
        };
        // The program's speed is kept (held speed, old KŘR at rest); the override scales what
        // the spindle is commanded, within the range's limit.
        self.speed_rpm = speed_rpm;
        let cap = if active { cap_rpm } else { gear.max_rpm };
        let speed_rpm = (speed_rpm * self.override_factor).min(cap.max(speed_rpm));
        let output = output_value(speed_rpm, &gear);
        publish_actuals(plc, &ext, active, radius_mm, &gear, speed_rpm, output);
        KrOutput {
            spindle_rpm: signed(p.dir, speed_rpm),
            speed_rpm,
            output,
            active,
            fault: None,
        }
    }

    /// Whether KŘR is on this tick (G96 or AKRR_REQ), keeping the speed KŘR ends at (SPEC
    /// §6: when KŘR ends, the last reached speed is kept; it becomes S while the program has
    /// no new S, the interpreter writes S = 0 when KŘR ends without S).
    fn update_active(&mut self, p: &ProgramSpindle, plc_request: bool) -> bool {
        if p.css {
            self.program_v_mm_min = self.cfg.s_word.cutting_speed_mm_min(p.s_word);
        }
        let active = plc_request || p.css;
        if self.active && !active {
            self.held_rpm = Some(self.speed_rpm);
        }
        if active || p.s_word > 0.0 {
            self.held_rpm = None;
        }
        self.active = active;
        active
    }

    /// The PLC's inputs where its control bits select them, else the program's values.
    fn external_inputs(
        &self,
        v2: bool,
        bits: u32,
        p: &ProgramSpindle,
        plc: &PlcArea,
    ) -> ExternalInputs {
        let on = |bit: u32| bits & bit != 0;
        let cell = |bit: u32, id: CellId| if on(bit) { plc.input(id) } else { 0 };
        // Limit: G76 or AKRR_SMAX (version 2 only), 0 = none; never above the gear maximum P.
        let limit_rpm = if !v2 {
            0.0
        } else if on(cntr::EXT_AKRR_SMAX) {
            f64::from(plc.input(CellId::AkrrSmax)) / MILLI_RPM_PER_RPM
        } else {
            p.limit_rpm.max(0.0)
        };
        ExternalInputs {
            limit_rpm,
            dist_raw: cell(cntr::EXT_AKRR_DIST, CellId::AkrrDist),
            vcorr_mm_min: cell(cntr::EXT_AKRR_VCORR, CellId::AkrrVcorr),
            v_mm_min: if on(cntr::EXT_AKRR_V) {
                f64::from(plc.input(CellId::AkrrV))
            } else {
                self.program_v_mm_min
            },
        }
    }

    /// Cutting radius from the controlling axis position (SPEC §6 **decide**, `docs/kr.md`):
    /// the program zero is on the spindle axis, so the distance from it is |x|, halved when the
    /// axis is programmed as a diameter.
    fn radius_of(&self, x_mm: f64) -> f64 {
        match self.cfg.radius_input {
            RadiusInput::Diameter => x_mm.abs() / 2.0,
            RadiusInput::Radius => x_mm.abs(),
        }
    }

    fn fault(&mut self, fault: KrFault, dir: SpindleDir, plc: &mut PlcArea) -> KrOutput {
        if fault == KrFault::BadPosition {
            // Keep the last speed and the cells as they are.
            let output = i32::clamp(plc.input(CellId::AkrrActOut), 0, 0x7FFF) as u16;
            return KrOutput {
                spindle_rpm: signed(dir, self.speed_rpm),
                speed_rpm: self.speed_rpm,
                output,
                active: self.active,
                fault: Some(fault),
            };
        }
        self.speed_rpm = 0.0;
        for c in [
            CellId::AkrrActP,
            CellId::AkrrActU,
            CellId::AkrrActS,
            CellId::AkrrActOut,
        ] {
            plc.set_act(c, 0);
        }
        KrOutput {
            active: self.active,
            fault: Some(fault),
            ..KrOutput::default()
        }
    }
}

/// n = v / (2π·r), clamped to `cap_rpm` (SPEC §6). On the spindle axis (r = 0) the cap applies;
/// no cutting speed gives 0.
pub fn speed_for(cutting_speed_mm_min: f64, radius_mm: f64, cap_rpm: f64) -> f64 {
    if cutting_speed_mm_min <= 0.0 {
        return 0.0;
    }
    if radius_mm <= 0.0 {
        return cap_rpm;
    }
    (cutting_speed_mm_min / (std::f64::consts::TAU * radius_mm)).min(cap_rpm)
}

/// Spindle output Ux = n/P·U, 0..U (SPEC §6).
pub fn output_value(speed_rpm: f64, gear: &Gear) -> u16 {
    let u = f64::from(gear.output_range);
    (speed_rpm / gear.max_rpm * u).round().clamp(0.0, u) as u16
}

fn signed(dir: SpindleDir, rpm: f64) -> f64 {
    match dir {
        SpindleDir::Cw => rpm,
        SpindleDir::Ccw => -rpm,
        SpindleDir::Stopped => 0.0,
    }
}

fn round_i32(v: f64) -> i32 {
    // `as` saturates at the i32 range and maps NaN to 0.
    v.round() as i32
}

/// Values KŘR works with this tick, from the PLC where its control bits say so (SPEC §6).
struct ExternalInputs {
    /// Speed limit (G76 or AKRR_SMAX), rpm; 0 = none.
    limit_rpm: f64,
    /// Distance added to the radius (AKRR_DIST), 1/8 µm.
    dist_raw: i32,
    /// Cutting speed correction (AKRR_VCORR), mm/min.
    vcorr_mm_min: i32,
    /// Cutting speed, mm/min.
    v_mm_min: f64,
}

/// Position of the controlling axis KŘR takes the radius from: the carriage itself with
/// AKRR_SUPORT, else the tool tip (carriage minus origin shift and length offset). `None`
/// when it is not a number.
fn controlling_x_mm(a: &ControllingAxis, carriage: bool) -> Option<f64> {
    let x_mm = if carriage {
        a.carriage_mm
    } else {
        a.carriage_mm - a.origin_shift_mm - a.length_offset_mm
    };
    x_mm.is_finite().then_some(x_mm)
}

/// Writes the AKRR_ACT_* cells the PLC reads back (SPEC §6).
fn publish_actuals(
    plc: &mut PlcArea,
    ext: &ExternalInputs,
    active: bool,
    radius_mm: f64,
    gear: &Gear,
    speed_rpm: f64,
    output: u16,
) {
    let v_mm_min = if active { round_i32(ext.v_mm_min) } else { 0 };
    plc.set_act(CellId::AkrrActV, v_mm_min);
    plc.set_act(
        CellId::AkrrActSmax,
        round_i32(ext.limit_rpm * MILLI_RPM_PER_RPM),
    );
    plc.set_act(CellId::AkrrActDist, ext.dist_raw);
    plc.set_act(CellId::AkrrActVcorr, ext.vcorr_mm_min);
    plc.set_act(CellId::AkrrActR, round_i32(radius_mm * EIGHTH_UM_PER_MM));
    plc.set_act(
        CellId::AkrrActP,
        round_i32(gear.max_rpm * MILLI_RPM_PER_RPM),
    );
    plc.set_act(CellId::AkrrActU, i32::from(gear.output_range));
    plc.set_act(CellId::AkrrActS, round_i32(speed_rpm * MILLI_RPM_PER_RPM));
    plc.set_act(CellId::AkrrActOut, i32::from(output));
}
