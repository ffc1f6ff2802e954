//! The tables a job's machine setup is built from: the machine constants (SPEC §1: the file,
//! the copy in force, the constants that wait for a restart), the offset table TAB0.KOR
//! (SPEC §3: its file and the memory copy programs use) and the work offsets G54..G59.3 of
//! ISO programs (their file), with the setup generation that counts their changes.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

use kernel::constants::Constants;
use kernel::machine::{MachineConfig, MachineSetup};
use kernel::offsets::work_file::WorkEdit;
use kernel::offsets::{OffsetTable, TableEdit, WorkOffsets};
use kernel::units::AxesMm;

use super::ControlError;
use super::startup::{LoadedStorage, machine_config};
use crate::runtime::config::{Config, RadiusInputConfig};
use crate::runtime::storage::{DiskChange, OffsetStore, StorageError, WorkOffsetStore};

/// Constants read only at daemon start: axis codes R0..R5 (checked against the configured
/// axes). Changing them is saved, listed in `restart_required` and not used before.
pub fn needs_restart(r: u16) -> bool {
    r <= 5
}

pub(super) struct Tables {
    config: Arc<Config>,
    /// The configuration's part of every job's machine setup.
    machine: MachineConfig,
    /// Machine constants (SPEC §1).
    constants: Mutex<ConstantsState>,
    /// TAB0.KOR: file and memory table (SPEC §3). Shared with the status thread, which applies
    /// the `G92` writes of executed blocks.
    offsets: Arc<Mutex<OffsetStore>>,
    /// Work offsets G54..G59.3: the file (no memory copy: programs change the run's copy).
    work: Mutex<WorkOffsetStore>,
    /// Increases whenever something a job's setup is built from changes (constants, offset
    /// table, also by `G92` writes): a program validated under another generation is
    /// validated again at start.
    generation: Arc<AtomicU64>,
    /// The block-delete switch (issue #31): `/` blocks are skipped while it is on.
    block_delete: AtomicBool,
}

/// The constants: the file's, and those in force (the file's, except the constants that
/// need a restart, which keep their value from start-up until then).
struct ConstantsState {
    saved: Constants,
    in_force: Constants,
    from_file: bool,
    /// The file's text as a person wrote it (issue #31: edits go into it in place).
    file: crate::runtime::storage::ConstantsFile,
}

impl ConstantsState {
    /// A constants file saved by hand since it was last seen becomes the saved constants, in
    /// force at once except those of [`needs_restart`]. Returns whether it changed.
    fn sync_with_disk(&mut self) -> Result<bool, StorageError> {
        let Some(c) = self.file.sync_with_disk()? else {
            return Ok(false);
        };
        let mut in_force = c.clone();
        for r in (0..=kernel::constants::MAX_R).filter(|&r| needs_restart(r)) {
            in_force.set(r, self.in_force.get(r));
        }
        self.saved = c;
        self.in_force = in_force;
        self.from_file = true;
        Ok(true)
    }
}

/// What a look at the data files found (see [`Tables::sync_files`]): per file, whether a
/// saved edit was loaded, or why the file on disk does not load (the memory copy is kept).
#[derive(Debug)]
pub struct FilesSync {
    pub offsets: Result<bool, StorageError>,
    pub constants: Result<bool, StorageError>,
    pub work_offsets: Result<bool, StorageError>,
}

impl Tables {
    /// The tables as loaded at start-up (see [`super::startup::load_storage`]).
    pub(super) fn new(config: Arc<Config>, stored: LoadedStorage) -> Tables {
        let constants = stored.constants;
        Tables {
            machine: machine_config(&config),
            config,
            constants: Mutex::new(ConstantsState {
                saved: constants.0.clone(),
                in_force: constants.0,
                from_file: constants.1,
                file: stored.constants_file,
            }),
            offsets: Arc::new(Mutex::new(stored.offsets)),
            work: Mutex::new(stored.work),
            generation: Arc::new(AtomicU64::new(0)),
            block_delete: AtomicBool::new(false),
        }
    }

    /// The block-delete switch: read when a job's setup is taken (a program validated with
    /// the other setting is validated again at start).
    pub(super) fn set_block_delete(&self, on: bool) {
        if self.block_delete.swap(on, Ordering::AcqRel) != on {
            self.generation.fetch_add(1, Ordering::AcqRel);
        }
    }

    pub(super) fn block_delete(&self) -> bool {
        self.block_delete.load(Ordering::Acquire)
    }

    /// The offset store, shared with the status thread (`G92` writes).
    pub(super) fn offsets_shared(&self) -> Arc<Mutex<OffsetStore>> {
        self.offsets.clone()
    }

    /// The setup generation, shared with the status thread (`G92` writes change it).
    pub(super) fn generation_shared(&self) -> Arc<AtomicU64> {
        self.generation.clone()
    }

    /// The setup generation now: what a validation records and a start compares.
    pub(super) fn generation(&self) -> u64 {
        self.generation.load(Ordering::Acquire)
    }

    fn changed(&self) {
        self.generation.fetch_add(1, Ordering::AcqRel);
    }

    /// The machine setup of a job started at `commanded`: the configuration (its default
    /// dialect), the constants in force, the memory offset table and the work offsets,
    /// decoded once (issue #14).
    pub(super) fn machine_setup(&self, commanded: AxesMm) -> Result<MachineSetup, ControlError> {
        let work = self.work_offsets();
        let c = self.constants.lock().unwrap();
        let offsets = self.offsets.lock().unwrap();
        MachineSetup::new(
            &self.machine,
            &c.in_force,
            c.from_file,
            offsets.memory(),
            commanded,
        )
        .map(|s| {
            s.with_block_delete(self.block_delete())
                .with_work_offsets(work)
        })
        .map_err(|e| ControlError::Invalid(format!("constant cutting speed: {e}")))
    }

    /// The work offsets programs start with (the file's, G54 in force).
    pub(super) fn work_offsets(&self) -> WorkOffsets {
        self.work.lock().unwrap().table()
    }

    /// The work offsets file's text and revision, as last seen on disk.
    pub(super) fn work_offsets_file(&self) -> (String, String) {
        let w = self.work.lock().unwrap();
        (w.file_text().to_string(), w.revision())
    }

    /// Operator edit of some axes of one work offset system, made on top of the file as it is
    /// on disk (a hand edit is loaded first and kept).
    pub(super) fn edit_work_offset(&self, edit: &WorkEdit) -> Result<(), ControlError> {
        let r = self.work.lock().unwrap().edit(edit);
        // A hand edit may have been loaded even when the edit itself was refused.
        self.changed();
        Ok(r?)
    }

    /// The memory offset table (what programs use).
    pub(super) fn offsets_memory(&self) -> OffsetTable {
        self.offsets.lock().unwrap().memory().clone()
    }

    /// The offset table file as text.
    pub(super) fn offsets_file_text(&self) -> String {
        self.offsets.lock().unwrap().file_text()
    }

    /// The revision of the offset table file's text (`storage::revision_of`).
    pub(super) fn offsets_revision(&self) -> String {
        self.offsets.lock().unwrap().revision()
    }

    /// Operator edit of one entry: file and memory (SPEC §3 b), made on top of the file as it
    /// is on disk (issue #31).
    pub(super) fn edit_offset(&self, edit: &TableEdit) -> Result<(), ControlError> {
        let r = self.offsets.lock().unwrap().operator_edit(edit);
        // A hand edit may have been loaded even when the edit itself was refused.
        self.changed();
        Ok(r?)
    }

    /// Replaces the whole file; memory becomes the file's table (SPEC §3 a). A rejected text
    /// changes nothing. With `base_revision`, refused when the file changed since.
    pub(super) fn replace_offsets_file(
        &self,
        text: &str,
        base_revision: Option<&str>,
    ) -> Result<(), ControlError> {
        let r = self
            .offsets
            .lock()
            .unwrap()
            .replace_file_text(text, base_revision);
        self.changed();
        Ok(r?)
    }

    /// Looks at TAB0.KOR, the constants and the work offsets files on disk: a saved edit is
    /// loaded into memory
    /// (SPEC §3: after every saved edit of the file), one that does not load is reported and
    /// memory kept. Blocks on disk IO.
    pub(super) fn sync_files(&self) -> FilesSync {
        let offsets = self
            .offsets
            .lock()
            .unwrap()
            .sync_with_disk()
            .map(|c| c == DiskChange::Loaded);
        let constants = self.constants.lock().unwrap().sync_with_disk();
        let work_offsets = self
            .work
            .lock()
            .unwrap()
            .sync_with_disk()
            .map(|c| c == DiskChange::Loaded);
        if [&offsets, &constants, &work_offsets]
            .iter()
            .any(|r| matches!(r, Ok(true)))
        {
            self.changed();
        }
        FilesSync {
            offsets,
            constants,
            work_offsets,
        }
    }

    /// Reloads the table from its file (power-on semantics).
    pub(super) fn reload_offsets(&self) -> Result<(), ControlError> {
        let path = self.config.storage.offsets_path();
        let fresh = OffsetStore::load_or_empty(path, &self.config.axis_names())?;
        *self.offsets.lock().unwrap() = fresh;
        self.changed();
        Ok(())
    }

    /// The constants as saved (the file; see [`needs_restart`] for those not yet in force).
    pub(super) fn constants(&self) -> Constants {
        self.constants.lock().unwrap().saved.clone()
    }

    /// The constants jobs start with now.
    pub(super) fn constants_in_force(&self) -> Constants {
        self.constants.lock().unwrap().in_force.clone()
    }

    /// The axis programmed (and shown) as a diameter: the controlling axis R67 in force when
    /// `[kr] radius_input = "diameter"` (docs/lathe.md). Its machine coordinates are radii.
    pub(super) fn diameter_axis(&self) -> Option<usize> {
        if self.config.kr.radius_input != RadiusInputConfig::Diameter {
            return None;
        }
        let letter = {
            let c = self.constants.lock().unwrap();
            kernel::kr::config::controlling_axis_letter(&c.in_force)?
        };
        self.config.axes.iter().position(|a| a.name == letter)
    }

    /// Sets machine constants and saves the constants file (the caller checks the machine is
    /// idle). Each is in force for every stage from the next start, except those of
    /// [`needs_restart`], which are saved and used from the next daemon start only. Refused
    /// (nothing changed) when the machine could not run with them. Returns the constants that
    /// need a restart.
    pub(super) fn set_constants(&self, values: &[(u16, f64)]) -> Result<Vec<u16>, ControlError> {
        let mut guard = self.constants.lock().unwrap();
        // Made on top of the file as it is on disk (issue #31).
        if guard.sync_with_disk()? {
            self.changed();
        }
        let mut saved = guard.saved.clone();
        let mut in_force = guard.in_force.clone();
        let mut restart = Vec::new();
        for &(r, v) in values {
            if r > kernel::constants::MAX_R {
                return Err(ControlError::Invalid(format!(
                    "R{r} does not exist: constants are R0..R{}",
                    kernel::constants::MAX_R
                )));
            }
            saved.set(r, v);
            if needs_restart(r) {
                if !restart.contains(&r) {
                    restart.push(r);
                }
            } else {
                in_force.set(r, v);
            }
        }
        // The next job's setup must build with them (KŘR refuses some values).
        MachineSetup::new(
            &self.machine,
            &in_force,
            true,
            &OffsetTable::new(),
            AxesMm::ZERO,
        )
        .map_err(|e| ControlError::Invalid(format!("constant cutting speed: {e}")))?;
        let milli: Vec<(u16, i64)> = values.iter().map(|&(r, _)| (r, saved.milli(r))).collect();
        let saved = guard.file.set(&saved, &milli)?;
        guard.saved = saved;
        guard.in_force = in_force;
        guard.from_file = true;
        self.changed();
        Ok(restart)
    }
}
