//! Validation and program selection: every text passes the whole pipeline against the machine
//! as it is now (the setup of the tables, from where the axes are), and a program that passed
//! may be selected; it remembers the setup generation it passed under.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

use kernel::Diagnostic;
use kernel::block::Block;
use kernel::machine::MachineSetup;
use kernel::pipeline::{self, Observer, Validation};
use kernel::program::Dialect;
use kernel::units::AxesMm;

use super::ControlError;
use super::rt_link::RtLink;
use super::tables::Tables;
use crate::runtime::library::ProgramText;
use crate::runtime::rt::{MachineState, Snapshot};

/// A program that passed validation. Only its text is kept (in memory, or the open file of a
/// stored program): blocks are streamed again when it runs, so a program of any size needs no
/// memory for its blocks.
pub struct LoadedProgram {
    pub name: String,
    pub text: ProgramText,
    /// The language it was validated in (and runs in).
    pub dialect: Dialect,
    /// Number of blocks.
    pub block_count: u32,
    pub warnings: Vec<Diagnostic>,
    /// Where the axes were when it was validated.
    pub start: AxesMm,
    /// The setup generation it was validated with (see `Tables::generation`).
    generation: u64,
    /// Where its last run from the first block started (`None`: it has not run).
    run_start: Mutex<Option<AxesMm>>,
}

impl LoadedProgram {
    /// Whether it was validated with the setup a job started at `snap` under setup generation
    /// `generation` would take: the same constants and offsets and the same start position.
    pub(super) fn validated_as(&self, snap: &Snapshot, generation: u64, axes: usize) -> bool {
        let now = SetupStamp {
            generation,
            start: snap.axes.commanded,
        };
        let then = SetupStamp {
            generation: self.generation,
            start: self.start,
        };
        then.matches(&now, axes)
    }

    /// A run of it from the first block starts at `at` (a restart's origin from now on).
    pub(super) fn note_run_start(&self, at: AxesMm) {
        *self.run_start.lock().unwrap() = Some(at);
    }

    /// Where a restart interprets the blocks before its block from (issue #31): where the
    /// last run of this program started, or where the axes were when it was loaded if it
    /// has not run since; so incremental (G91) moves before the block land where an
    /// uninterrupted run's did, wherever the axes are now.
    pub fn restart_origin(&self) -> AxesMm {
        self.run_start.lock().unwrap().unwrap_or(self.start)
    }
}

/// What the machine setup of a pass is known by: the setup generation (constants, offsets,
/// `G92`) and the start position. Two passes of one text with matching stamps are the same.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SetupStamp {
    pub generation: u64,
    pub start: AxesMm,
}

impl SetupStamp {
    /// The stamp of a pass made with `setup` under `generation`.
    pub fn of(setup: &MachineSetup, generation: u64) -> Self {
        SetupStamp {
            generation,
            start: setup.program().start,
        }
    }

    /// The same generation and start position on the first `axes` axes.
    pub fn matches(&self, other: &SetupStamp, axes: usize) -> bool {
        self.generation == other.generation
            && (0..axes).all(|i| (self.start[i] - other.start[i]).abs() <= 1e-9)
    }
}

/// The selected program and the count of validation passes.
#[derive(Default)]
pub(super) struct Selection {
    program: Mutex<Option<Arc<LoadedProgram>>>,
    /// See [`super::Controller::validation_passes`].
    passes: AtomicU64,
}

impl Selection {
    pub(super) fn program(&self) -> Option<Arc<LoadedProgram>> {
        self.program.lock().unwrap().clone()
    }

    /// Makes a validated program the selected one. Refused while a program runs.
    pub(super) fn select(
        &self,
        snap: &Snapshot,
        loaded: Arc<LoadedProgram>,
    ) -> Result<(), ControlError> {
        let running = matches!(
            snap.state,
            MachineState::Running | MachineState::Hold | MachineState::Stopping
        );
        if running {
            return Err(ControlError::WrongState(
                "a program is running: stop it before loading another".into(),
            ));
        }
        let mut selected = self.program.lock().unwrap();
        // The same program loaded again (edited, or re-selected after a stop) keeps where its
        // last run started: a restart's scan must start there, not where the axes stopped.
        let kept = selected
            .as_ref()
            .filter(|p| p.name == loaded.name)
            .and_then(|p| *p.run_start.lock().unwrap());
        if let Some(at) = kept {
            loaded.note_run_start(at);
        }
        *selected = Some(loaded);
        Ok(())
    }

    pub(super) fn passes(&self) -> u64 {
        self.passes.load(Ordering::Relaxed)
    }

    pub(super) fn count_pass(&self) {
        self.passes.fetch_add(1, Ordering::Relaxed);
    }

    /// The setup in force (with `modal`, for a program in `dialect`) and its generation, and
    /// `pass`'s verdict with it.
    pub(super) fn validate_by(
        &self,
        rt: &RtLink,
        tables: &Tables,
        modal: Option<kernel::program::Modal>,
        dialect: Dialect,
        pass: impl FnOnce(&MachineSetup) -> Validation,
    ) -> Result<(Validation, MachineSetup, u64), ControlError> {
        let generation = tables.generation();
        let setup = tables
            .machine_setup(rt.snapshot().axes.commanded)?
            .with_modal(modal)
            .with_dialect(dialect);
        self.count_pass();
        let v = pass(&setup);
        Ok((v, setup, generation))
    }

    /// Validates `text` (in memory or a stored program's file) in `dialect` by `pass` (which
    /// reads it) into a program that may be selected, with the setup it was validated with.
    /// Errors: the program's diagnostics.
    pub(super) fn prepare_program(
        &self,
        rt: &RtLink,
        tables: &Tables,
        name: &str,
        text: ProgramText,
        dialect: Dialect,
        pass: impl FnOnce(&MachineSetup) -> Validation,
    ) -> Result<(Arc<LoadedProgram>, MachineSetup), ControlError> {
        let (v, setup, generation) = self.validate_by(rt, tables, None, dialect, pass)?;
        if v.has_errors() {
            return Err(ControlError::InvalidProgram(v.diagnostics));
        }
        let loaded = Arc::new(LoadedProgram {
            name: name.to_owned(),
            text,
            dialect,
            block_count: v.blocks,
            warnings: v.diagnostics,
            start: setup.program().start,
            generation,
            run_start: Mutex::new(None),
        });
        Ok((loaded, setup))
    }
}

/// An observer that keeps nothing (the validation is returned separately).
pub(super) struct NoObserver;

impl Observer for NoObserver {
    fn segment(&mut self, _s: &kernel::plan::Segment) -> pipeline::Flow {
        pipeline::Flow::Go
    }
}

/// Keeps the programmed blocks (MDI and single-block runs: status shows their modal state).
#[derive(Default)]
pub(super) struct Blocks(pub(super) Vec<Block>);

impl Observer for Blocks {
    fn programmed(&mut self, b: &Block, _modal: &kernel::program::Modal) {
        self.0.push(*b);
    }
    fn segment(&mut self, _s: &kernel::plan::Segment) -> pipeline::Flow {
        pipeline::Flow::Go
    }
}

/// Keeps the legs of a restart's approach (the previews draw them apart).
#[derive(Default)]
pub(super) struct ApproachLegs(pub(super) Vec<Block>);

impl Observer for ApproachLegs {
    fn approach(&mut self, leg: &Block) {
        self.0.push(*leg);
    }
    fn segment(&mut self, _s: &kernel::plan::Segment) -> pipeline::Flow {
        pipeline::Flow::Go
    }
}
