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
use crate::offsets::WorkOffsets;
use crate::plan::PlannerConfig;
use crate::program::{Dialect, IjMode, Modal, Setup};
use crate::units::{AxesMm, MAX_AXES};

pub mod names;

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
    /// M functions on the machine's outputs (`[io]`, docs/io.md).
    pub m_outputs: crate::outputs::MFunctions,
    /// Automatic tool changer: how many outputs carry the tool number (`None`: any tool).
    pub tool_number_bits: Option<u8>,
    pub radius_input: RadiusInput,
    /// Encoder pulses per revolution of each rotary axis, in machine order (`None`: linear).
    pub rotary_pulses_per_rev: Vec<Option<f64>>,
    pub ij: IjMode,
    /// Code page of program files (`[program] encoding`, issue #31).
    pub encoding: crate::program::encoding::TextEncoding,
    /// The machine's default program language (`[program] dialect`); a program's file name
    /// or the API's `dialect` field may choose the other ([`MachineSetup::with_dialect`]).
    pub dialect: Dialect,
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
    preview_page_blocks: u32,
    /// Where the run of the program a restart resumes started (issue #31): the blocks
    /// before the restart block are interpreted from there; `None`: from `program.start`.
    restart_origin: Option<AxesMm>,
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
        program.encoding = machine.encoding;
        program.dialect = machine.dialect;
        program.preprocessor = machine.preprocessor;
        program.soft_limits = machine.soft_limits;
        // Gears select by M code; the fastest axis is Vmax of the βmax warning (SPEC §5, §6).
        program.gears = machine.gears.clone();
        program.m_outputs = machine.m_outputs.clone();
        program.tool_number_bits = machine.tool_number_bits;
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
            preview_page_blocks: constants.preview_page_blocks(),
            restart_origin: None,
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
        let preview_page_blocks = program.constants.preview_page_blocks();
        MachineSetup {
            program,
            comp,
            planner,
            kr: None,
            in_position_mm,
            preview_page_blocks,
            restart_origin: None,
        }
    }

    /// G24 in-position window per axis (R6, R7), mm.
    pub fn in_position_mm(&self) -> AxesMm {
        self.in_position_mm
    }

    /// Blocks per preview page (R387, 0 = all).
    pub fn preview_page_blocks(&self) -> u32 {
        self.preview_page_blocks
    }

    /// The same setup for a program starting in modal state `modal` (MDI inherits the state
    /// the last program or MDI left, docs/language.md); `None`: the power-on state.
    pub fn with_modal(mut self, modal: Option<Modal>) -> Self {
        self.program.modal = modal;
        self
    }

    /// The same setup for a restart (`Options::from_block`) of a program whose run started at
    /// `origin`: the blocks before the restart block are interpreted from there, as an
    /// uninterrupted run does (incremental moves), while the approach starts where the axes
    /// are. `None`: from where the axes are.
    pub fn with_restart_origin(mut self, origin: Option<AxesMm>) -> Self {
        self.restart_origin = origin;
        self
    }

    /// See [`MachineSetup::with_restart_origin`].
    pub fn restart_origin(&self) -> Option<AxesMm> {
        self.restart_origin
    }

    /// The same setup with the block-delete switch `on` (docs/language.md "Block delete").
    pub fn with_block_delete(mut self, on: bool) -> Self {
        self.program.block_delete = on;
        self
    }

    /// The same setup for a program in `dialect` (the machine's default, a file name's or
    /// the API's choice).
    pub fn with_dialect(mut self, dialect: Dialect) -> Self {
        self.program.dialect = dialect;
        self
    }

    /// The same setup with the work offsets G54..G59.3 of the storage's file (the run works
    /// on a copy: `G10 L2/L20` never reach the file).
    pub fn with_work_offsets(mut self, work: WorkOffsets) -> Self {
        self.program.work_offsets = work;
        self
    }
}

/// Who reads a constant.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reader {
    /// Read once at daemon start (the axis codes R0..R5): listed in `restart_required`.
    DaemonStart,
    Interpreter,
    Compensation,
    Planner,
    /// Constant cutting speed and the spindle on the RT thread.
    Kr,
    /// The G24 in-position window on the RT thread.
    G24Window,
    Preview,
}

/// Constants `first..=last` and who reads them.
#[derive(Clone, Copy, Debug)]
pub struct ConstantUse {
    pub first: u16,
    pub last: u16,
    pub readers: &'static [Reader],
    pub meaning: &'static str,
}

const fn used(
    first: u16,
    last: u16,
    readers: &'static [Reader],
    meaning: &'static str,
) -> ConstantUse {
    ConstantUse {
        first,
        last,
        readers,
        meaning,
    }
}

/// Every constant the controller reads (SPEC sections in the accessors). All but R0..R5 are
/// decoded by [`MachineSetup::new`] (a unit test below checks this table against what it
/// decodes); the daemon-level tests of each are listed in `tests/tests/constants_next_start.rs`.
pub const CONSTANTS_READ: &[ConstantUse] = {
    use Reader::*;
    &[
        used(
            0,
            5,
            &[DaemonStart, Interpreter, Kr],
            "axis codes (restart)",
        ),
        used(6, 6, &[G24Window], "in-position window, axes 1..3"),
        used(7, 7, &[G24Window], "in-position window, axes 4..6"),
        used(39, 39, &[Planner], "smooth-junction angle"),
        used(52, 52, &[Planner], "acceleration to a stop"),
        used(55, 55, &[Interpreter, Compensation], "arc end tolerance"),
        used(67, 67, &[Interpreter, Kr], "KŘR controlling axis"),
        used(95, 95, &[Compensation], "radius compensation enabled"),
        used(97, 97, &[Planner], "continuity rule"),
        used(
            232,
            232,
            &[Planner],
            "arc chord error, old centripetal limit",
        ),
        used(234, 234, &[Compensation], "continuity angle limit"),
        used(236, 236, &[Planner], "acceleration in continuous moves"),
        used(237, 237, &[Planner], "acceleration of rapids"),
        used(325, 325, &[Interpreter], "preprocessor refinement"),
        used(329, 329, &[Interpreter, Kr], "S units, G96/G97 meaning"),
        used(338, 338, &[Planner], "acceleration profile"),
        used(
            339,
            339,
            &[Interpreter, Compensation],
            "compensation corners, G40",
        ),
        used(382, 382, &[Planner], "short-block break length"),
        used(383, 383, &[Planner], "short-block merge length"),
        used(384, 384, &[Planner], "contour accuracy, speed drop"),
        used(385, 385, &[Planner], "overload acceleration"),
        used(387, 387, &[Preview], "blocks per preview page"),
        used(395, 395, &[Planner], "ramp rise time"),
        used(397, 397, &[Interpreter, Compensation], "compensation rules"),
        used(406, 429, &[Planner], "dynamic sets 1..4"),
        used(430, 432, &[Planner], "rapid and stop set"),
        used(580, 580, &[Kr], "KŘR version"),
        used(
            764,
            764,
            &[Compensation],
            "short-block report / optimisation",
        ),
        used(765, 765, &[Compensation], "gouge report / optimisation"),
    ]
};

/// Every constant number of [`CONSTANTS_READ`], ascending.
pub fn constants_read() -> impl Iterator<Item = u16> {
    CONSTANTS_READ.iter().flat_map(|u| u.first..=u.last)
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
            m_outputs: Default::default(),
            tool_number_bits: None,
            gears: vec![Gear {
                max_rpm: 6000.0,
                output_range: 0x7FFF,
                m_code: Some(41),
            }],
            radius_input: RadiusInput::Radius,
            rotary_pulses_per_rev: Vec::new(),
            ij: IjMode::default(),
            encoding: Default::default(),
            dialect: Dialect::Cnc836,
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

    /// What the stages decoded from the constants (the raw constants the interpreter's setup
    /// carries are left out: the interpreter's decoding is in its rules).
    fn decoded(s: &Result<MachineSetup, KrConfigError>) -> String {
        match s {
            Err(e) => format!("refused: {e:?}"),
            Ok(s) => format!(
                "{:?} {:?} {:?} {:?} {} {}",
                s.comp(),
                s.planner(),
                s.kr_constants(),
                s.in_position_mm(),
                s.preview_page_blocks(),
                crate::program::Interpreter::new(s.program()).decoded_rules()
            ),
        }
    }

    /// Constants `base` decodes differently when one of them changes alone (each digit, each
    /// sign).
    fn constants_read_from(base: &Constants, range: std::ops::RangeInclusive<u16>) -> Vec<u16> {
        // Six axes: KŘR's axis may be any of R0..R5.
        let mut machine = mill();
        for name in ['U', 'V', 'W'] {
            let mut a = machine.axes[0];
            a.name = name;
            machine.axes.push(a);
        }
        let build =
            |c: &Constants| MachineSetup::new(&machine, c, true, &OffsetTable::new(), AxesMm::ZERO);
        let reference = decoded(&build(base));
        assert!(!reference.starts_with("refused"), "{reference}");
        let mut read = Vec::new();
        for r in range {
            let changes = (0..8u32).flat_map(|d| {
                [1i64, 2, 3, 4, 5, 9]
                    .into_iter()
                    .flat_map(move |k| [k * 10i64.pow(d), -k * 10i64.pow(d)])
            });
            let reads = changes.into_iter().any(|milli| {
                let mut c = base.clone();
                c.set(r, milli as f64 / 1000.0);
                decoded(&build(&c)) != reference
            });
            if reads {
                read.push(r);
            }
        }
        read
    }

    /// Changes each digit and the sign of every constant R0..R999 alone and lists those whose
    /// change reaches what the setup decodes: they must be exactly the table's. Twice: with
    /// the default constants and with the dynamic sets and the rapid set switched on (their
    /// values are read only then), and R0..R5 with X, KŘR's axis, coded in each of them. A constant a
    /// stage starts reading fails this until it is listed (and given a daemon-level test).
    #[test]
    fn the_table_lists_every_constant_the_setup_decodes() {
        let all = 0..=crate::constants::MAX_R;
        let mut sets_on = Constants::new();
        for (k, r) in [406u16, 412, 418, 424, 430].into_iter().enumerate() {
            sets_on.set(r, 0.001);
            // An acceleration of its own, so that switching the set off shows.
            sets_on.set(r + 2, 0.1 * (k + 1) as f64);
        }
        let mut read = constants_read_from(&Constants::new(), all.clone());
        read.extend(constants_read_from(&sets_on, all));
        for axis in 1..=6 {
            let mut c = Constants::new();
            // R67 = 1 (X): KŘR's axis is where R0..R5 code X; code it in R(k-1) only.
            c.set(67, 1.0);
            for r in 0..6 {
                let code = if r + 1 == axis { 1.0 } else { 4.0 + r as f64 };
                c.set(r, code);
            }
            read.extend(constants_read_from(&c, 0..=5));
        }
        read.sort();
        read.dedup();
        assert_eq!(read, constants_read().collect::<Vec<_>>());
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
