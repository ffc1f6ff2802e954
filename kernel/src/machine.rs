//! One machine setup per job: the configuration, the machine constants and the offset table,
//! decoded once, in one place, into what every stage reads (issue #14).
//!
//! A job takes a [`MachineSetup`] when it starts and every consumer reads that snapshot: the
//! interpreter ([`MachineSetup::program`]), the compensator ([`MachineSetup::comp`]), the
//! planner ([`MachineSetup::planner`]), the interpolator's G24 window
//! ([`MachineSetup::in_position_mm`]) and constant cutting speed / the spindle
//! ([`MachineSetup::kr`]). A constants change is therefore in force for all of them at the next
//! start, never for some of them only.

use crate::comp::CompConfig;
use crate::constants::Constants;
use crate::kr::{Gear, KrConfig, KrConfigError, KrConstants, RadiusInput};
use crate::offsets::OffsetTable;
use crate::plan::PlannerConfig;
use crate::program::{IjMode, Modal, Setup};
use crate::units::{AxesMm, MAX_AXES};

/// Limits of one configured axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AxisLimits {
    pub name: char,
    /// Also the rapid speed, mm/min.
    pub max_velocity_mm_min: f64,
    pub max_accel_mm_s2: f64,
}

/// What the configuration file says about the machine (fixed for the daemon's life).
#[derive(Clone, Debug, PartialEq)]
pub struct MachineConfig {
    pub axes: Vec<AxisLimits>,
    /// Spindle gear ranges (KŘR, SPEC §6).
    pub gears: Vec<Gear>,
    pub radius_input: RadiusInput,
    /// Encoder pulses per revolution of each rotary axis, in machine order (`None`: linear).
    pub rotary_pulses_per_rev: Vec<Option<f64>>,
    pub ij: IjMode,
    /// `$63`: the preprocessor is on (R325 refinement).
    pub preprocessor: bool,
    /// Minimum block duration of the planner (`[planner] min_block_time_ms`; 0: as many
    /// blocks per tick as the criteria allow, 4 ms: CNC8x9 compatibility), s.
    pub min_block_time_s: f64,
    /// Travel limits per axis in machine coordinates (issue #15).
    pub soft_limits: crate::limits::SoftLimits,
}

impl MachineConfig {
    pub fn axis_names(&self) -> Vec<char> {
        self.axes.iter().map(|a| a.name).collect()
    }
}

/// Everything a job reads about the machine, decoded once.
#[derive(Clone, Debug)]
pub struct MachineSetup {
    program: Setup,
    comp: CompConfig,
    planner: PlannerConfig,
    /// `None` only for tools without a machine configuration ([`MachineSetup::from_stages`]).
    kr: Option<KrConfig>,
    in_position_mm: AxesMm,
}

impl MachineSetup {
    /// Decodes `constants` for every stage. `constants_from_file`: without a constants file
    /// the envelope settings are the axis limits alone (see [`planner_config`]). Refused when a
    /// constant has a value the controller cannot run with (KŘR's R67, R329, R580, the gears).
    pub fn new(
        machine: &MachineConfig,
        constants: &Constants,
        constants_from_file: bool,
        offsets: &OffsetTable,
        start: AxesMm,
    ) -> Result<Self, KrConfigError> {
        let mut program = Setup::new(&machine.axis_names());
        program.start = start;
        program.constants = constants.clone();
        program.offsets = offsets.clone();
        program.ij = machine.ij;
        program.preprocessor = machine.preprocessor;
        program.soft_limits = machine.soft_limits;
        // Gears select by M code; the fastest axis is Vmax of the βmax warning (SPEC §5, §6).
        program.gears = machine.gears.clone();
        program.max_feed_mm_min = machine
            .axes
            .iter()
            .map(|a| a.max_velocity_mm_min)
            .fold(0.0, f64::max);
        // Every stage after the interpreter works in radius (the true XZ geometry): the
        // interpreter halves the diameter axis's values, so KŘR reads positions as radii.
        let kr = KrConfig::from_constants(constants, RadiusInput::Radius, machine.gears.clone())?;
        program.diameter_axis = diameter_axis(machine, &kr);
        for (k, p) in machine
            .rotary_pulses_per_rev
            .iter()
            .enumerate()
            .take(MAX_AXES)
        {
            program.rotary_kpulses_per_rev[k] = p.map_or(0.0, |p| p / 1000.0);
        }
        Ok(MachineSetup {
            program,
            comp: CompConfig::from_constants(constants),
            planner: planner_config(machine, constants, constants_from_file),
            kr: Some(kr),
            in_position_mm: constants.in_position_window_mm(),
        })
    }

    /// The interpreter's setup: axes, start position, constants, memory offset table.
    pub fn program(&self) -> &Setup {
        &self.program
    }

    /// Radius compensation settings (R95, R234, R339, R397, R764, R765, R55).
    pub fn comp(&self) -> CompConfig {
        self.comp
    }

    /// Planner limits and envelope settings (axis limits, R39, R52, R97, R236, R237, R338 ...).
    pub fn planner(&self) -> &PlannerConfig {
        &self.planner
    }

    /// Constant cutting speed: the gear table and R67, R329 d3, R580.
    pub fn kr(&self) -> Option<&KrConfig> {
        self.kr.as_ref()
    }

    /// The constants' part of [`MachineSetup::kr`], handed to the RT thread with a job's start.
    pub fn kr_constants(&self) -> Option<KrConstants> {
        self.kr.as_ref().map(KrConfig::constants)
    }

    /// A setup for tools that have no machine configuration (the preview's command line, benches):
    /// the stages' settings as given, no spindle.
    pub fn from_stages(program: Setup, comp: CompConfig, planner: PlannerConfig) -> Self {
        let in_position_mm = program.constants.in_position_window_mm();
        MachineSetup {
            program,
            comp,
            planner,
            kr: None,
            in_position_mm,
        }
    }

    /// G24 in-position window per axis (R6, R7), mm.
    pub fn in_position_mm(&self) -> AxesMm {
        self.in_position_mm
    }

    /// The same setup for a program starting in modal state `modal` (MDI inherits the state
    /// the last program or MDI left, docs/language.md); `None`: the power-on state.
    pub fn with_modal(mut self, modal: Option<Modal>) -> Self {
        self.program.modal = modal;
        self
    }
}

/// The axis programmed as a diameter: the controlling axis of KŘR (R67) when the machine is
/// set to `radius_input = "diameter"` (a lathe's X), otherwise none (docs/lathe.md).
pub fn diameter_axis(machine: &MachineConfig, kr: &KrConfig) -> Option<usize> {
    let k = kr.controlling_axis;
    (machine.radius_input == RadiusInput::Diameter && k < machine.axes.len()).then_some(k)
}

/// The planner's configuration from the axis limits and the constants: the one function that
/// builds it (daemon, preview, benches). The envelope settings come from the constants when the
/// machine has a constants file; otherwise each move is limited by the axes it moves (#24).
pub fn planner_config(
    machine: &MachineConfig,
    constants: &Constants,
    constants_from_file: bool,
) -> PlannerConfig {
    let axes: Vec<crate::plan::AxisLimits> = machine
        .axes
        .iter()
        .map(|a| crate::plan::AxisLimits {
            v_max_mm_s: a.max_velocity_mm_min / 60.0,
            a_max_mm_s2: a.max_accel_mm_s2,
        })
        .collect();
    PlannerConfig::for_machine(
        &axes,
        machine.min_block_time_s,
        constants_from_file.then_some(constants),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mill() -> MachineConfig {
        let axis = |name| AxisLimits {
            name,
            max_velocity_mm_min: 12_000.0,
            max_accel_mm_s2: 800.0,
        };
        MachineConfig {
            axes: vec![axis('X'), axis('Y'), axis('Z')],
            gears: vec![Gear {
                max_rpm: 6000.0,
                output_range: 0x7FFF,
                m_code: Some(41),
            }],
            radius_input: RadiusInput::Radius,
            rotary_pulses_per_rev: Vec::new(),
            ij: IjMode::default(),
            preprocessor: true,
            min_block_time_s: 0.0,
            soft_limits: crate::limits::SoftLimits::NONE,
        }
    }

    fn setup(c: &Constants) -> MachineSetup {
        MachineSetup::new(&mill(), c, true, &OffsetTable::new(), AxesMm::ZERO).unwrap()
    }

    #[test]
    fn one_r55_for_interpreter_and_compensator() {
        for r55 in [0.0, 0.005, 0.02] {
            let mut c = Constants::new();
            c.set(55, r55);
            let s = setup(&c);
            assert_eq!(s.comp().arc_end_tolerance_mm, c.arc_tolerance_mm());
            assert_eq!(
                s.program().constants.arc_tolerance_mm(),
                c.arc_tolerance_mm()
            );
        }
    }

    #[test]
    fn kr_and_g24_window_come_from_the_same_constants() {
        let mut c = Constants::new();
        c.set(329, 0.2);
        c.set(67, 2.0);
        c.set(6, 0.02);
        c.set(7, 0.5);
        let s = setup(&c);
        let k = s.kr_constants().unwrap();
        assert!(k.s_word.s_in_m_min);
        assert_eq!(k.controlling_axis, 1);
        assert_eq!(s.in_position_mm()[0], 0.02);
        assert_eq!(s.in_position_mm()[2], 0.02);
        assert_eq!(s.in_position_mm()[3], 0.5);
        c.set(580, 7.0);
        assert!(MachineSetup::new(&mill(), &c, true, &OffsetTable::new(), AxesMm::ZERO).is_err());
    }
}
