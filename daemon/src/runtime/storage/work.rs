//! The work offsets file (`[storage] work_offsets_file`, `WORK.OFS`; format in
//! `kernel::offsets::work_file`, docs/files.md): the nine systems G54..G59.3 of ISO programs.
//!
//! As TAB0.KOR, **the file on disk is the truth**: it is read at start, looked at again before
//! every edit and by the daemon's file watch, and an edit is made in its text as it is on
//! disk then (a hand edit saved since is never overwritten) and written atomically. There is
//! no memory copy a program could change: a program's `G10 L2/L20` works on the run's copy
//! (`kernel::program::Setup::work_offsets`).

use std::path::{Path, PathBuf};

use kernel::Diagnostic;
use kernel::offsets::WorkOffsets;
use kernel::offsets::work_file::{self, WorkEdit};

use super::{
    DiskChange, Fingerprint, StorageError, fingerprint, io_err, read_disk, revision_of, utf8,
    write_atomic,
};

/// The work offsets: the file's text and table as last seen on disk (or written).
#[derive(Debug)]
pub struct WorkOffsetStore {
    path: PathBuf,
    axis_names: Vec<char>,
    /// The text as last seen or written ("" while there is no file).
    text: String,
    /// The table of the last text that loaded.
    table: WorkOffsets,
    seen: Option<Fingerprint>,
    /// The text on disk does not load (a hand edit): why. `table` is the last good one.
    disk_error: Option<Vec<Diagnostic>>,
}

impl WorkOffsetStore {
    /// Start-up: the file's offsets, all zero without a file (created by the first edit). A
    /// file that exists and does not load is refused (running with wrong offsets scraps parts).
    pub fn load_or_empty(
        path: impl Into<PathBuf>,
        axis_names: &[char],
    ) -> Result<Self, StorageError> {
        let mut s = WorkOffsetStore {
            path: path.into(),
            axis_names: axis_names.to_vec(),
            text: String::new(),
            table: WorkOffsets::default(),
            seen: None,
            disk_error: None,
        };
        match s.sync_with_disk() {
            Ok(_) => Ok(s),
            Err(StorageError::DiskInvalid { path, diagnostics }) => {
                Err(StorageError::Invalid { path, diagnostics })
            }
            Err(e) => Err(e),
        }
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The offsets programs start with (the last text that loaded; G54 in force at start).
    pub fn table(&self) -> WorkOffsets {
        self.table
    }

    /// The file's text as last seen ("" without a file; a hand edit that does not load
    /// included, see [`WorkOffsetStore::disk_error`]).
    pub fn file_text(&self) -> &str {
        &self.text
    }

    /// The revision of [`WorkOffsetStore::file_text`] (see [`revision_of`]); empty without a
    /// file.
    pub fn revision(&self) -> String {
        self.seen.as_ref().map(revision_of).unwrap_or_default()
    }

    /// Why the text on disk does not load, when it does not.
    pub fn disk_error(&self) -> Option<&[Diagnostic]> {
        self.disk_error.as_deref()
    }

    /// Looks at the file: a text saved since it was last seen is loaded; one that does not
    /// load is refused with its lines and codes (`storage_file_invalid`, again while the file
    /// stays so) and the last good table is kept.
    pub fn sync_with_disk(&mut self) -> Result<DiskChange, StorageError> {
        let Some(bytes) = read_disk(&self.path)? else {
            return Ok(DiskChange::Missing);
        };
        let f = fingerprint(&bytes);
        if self.seen != Some(f) {
            self.seen = Some(f);
            let parsed = utf8(bytes).and_then(|t| {
                let p = work_file::parse(&t, &self.axis_names);
                self.text = t;
                p
            });
            match parsed {
                Ok(table) => {
                    self.table = table;
                    self.disk_error = None;
                    return Ok(DiskChange::Loaded);
                }
                Err(d) => self.disk_error = Some(d),
            }
        }
        match &self.disk_error {
            Some(d) => Err(StorageError::DiskInvalid {
                path: self.path.clone(),
                diagnostics: d.clone(),
            }),
            None => Ok(DiskChange::Unchanged),
        }
    }

    /// An operator edit: the values named change in the file's text as it is on disk now (a
    /// hand edit saved since is loaded first and kept), written atomically. All or nothing.
    pub fn edit(&mut self, edit: &WorkEdit) -> Result<(), StorageError> {
        self.sync_with_disk()?;
        let base = if self.seen.is_none() {
            work_file::HEADER
        } else {
            &self.text
        };
        let (text, table) =
            work_file::edit_text(base, edit, &self.axis_names).map_err(|diagnostics| {
                StorageError::Invalid {
                    path: self.path.clone(),
                    diagnostics,
                }
            })?;
        write_atomic(&self.path, text.as_bytes()).map_err(io_err(&self.path))?;
        self.seen = Some(fingerprint(text.as_bytes()));
        self.text = text;
        self.table = table;
        self.disk_error = None;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use kernel::units::MAX_AXES;

    fn dir(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("cncd-work-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    fn set(system: usize, axis: usize, v: f64) -> WorkEdit {
        let mut values = [None; MAX_AXES];
        values[axis] = Some(v);
        WorkEdit { system, values }
    }

    #[test]
    fn edits_go_on_top_of_the_file_on_disk() {
        let d = dir("edit");
        let path = d.join("WORK.OFS");
        let mut s = WorkOffsetStore::load_or_empty(&path, &['X', 'Y', 'Z']).unwrap();
        assert_eq!(s.table(), WorkOffsets::default());
        s.edit(&set(1, 0, 10.0)).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.starts_with(work_file::HEADER) && text.ends_with("G55 X10.000\n"));
        // A hand edit, then an API edit: both are in the file.
        std::fs::write(&path, format!("{text}G54 Z-5 ; by hand\n")).unwrap();
        s.edit(&set(1, 1, -2.5)).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.contains("G55 X10.000 Y-2.500\n"), "{text}");
        assert!(text.contains("G54 Z-5 ; by hand\n"), "{text}");
        assert_eq!(s.table().systems[0][2], -5.0);
        // A hand edit that does not load: kept on disk, edits refused, the table kept.
        std::fs::write(&path, "G54 Q1\n").unwrap();
        let e = s.edit(&set(0, 0, 1.0)).unwrap_err();
        assert_eq!(e.code(), "storage_file_invalid");
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "G54 Q1\n");
        assert_eq!(s.table().systems[1][0], 10.0);
        // ... and refused at start-up.
        let e = WorkOffsetStore::load_or_empty(&path, &['X', 'Y', 'Z']).unwrap_err();
        assert_eq!(e.code(), "storage_invalid");
        std::fs::remove_dir_all(&d).unwrap();
    }
}
