//! Durable file storage: atomic replacement of TAB0.KOR and the constants file, and the offset
//! table's two copies, file and memory (SPEC §3).
//!
//! Every write goes through [`write_atomic`]: the new content is written to a temporary file in
//! the same directory, flushed to disk (`fsync`), renamed over the old file, and the directory
//! is flushed so the rename itself survives a power cut. A crash at any moment leaves either the
//! old or the new file, never a mix (tested by `daemon/tests/storage_kill.rs`, which SIGKILLs a
//! writer hundreds of times).
//!
//! The calls block on disk IO: from async code run them in `tokio::task::spawn_blocking`.
//! One [`OffsetStore`] per file and one writer at a time (the temporary name is fixed).

use std::fs::{self, File, OpenOptions};
use std::io::{self, Write};
use std::path::{Path, PathBuf};

use kernel::Diagnostic;
use kernel::constants::Constants;
use kernel::offsets::{self, KorFile, OffsetTable, TableEdit};

/// Why a storage operation failed. Nothing was changed (neither file nor memory).
#[derive(Debug, thiserror::Error)]
pub enum StorageError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: io::Error,
    },
    /// The text was refused; the messages say where and why.
    #[error("{}: {}", path.display(), join(diagnostics))]
    Invalid {
        path: PathBuf,
        diagnostics: Vec<Diagnostic>,
    },
}

impl StorageError {
    /// Stable code (tests and HMIs match it; the message may improve).
    pub fn code(&self) -> &'static str {
        match self {
            StorageError::Io { .. } => "storage_io",
            StorageError::Invalid { .. } => "storage_invalid",
        }
    }
}

fn join(d: &[Diagnostic]) -> String {
    d.iter()
        .map(ToString::to_string)
        .collect::<Vec<_>>()
        .join("; ")
}

/// Name of the temporary file used while replacing `path` (same directory, so the rename is
/// atomic; fixed, so an interrupted write leaves at most one stale temporary, overwritten next
/// time).
pub fn temp_path(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(".{name}.tmp"))
}

/// Replaces `path` with `bytes` atomically and durably: temp file, fsync, rename, fsync of the
/// directory. On error the old file is untouched.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> io::Result<()> {
    let tmp = temp_path(path);
    let result = (|| {
        let mut f = OpenOptions::new()
            .write(true)
            .create(true)
            .truncate(true)
            .open(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        drop(f);
        fs::rename(&tmp, path)
    })();
    if let Err(e) = result {
        let _ = fs::remove_file(&tmp);
        return Err(e);
    }
    // The rename is a change of the directory: flush it too.
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    File::open(dir)?.sync_all()
}

fn io_err(path: &Path) -> impl FnOnce(io::Error) -> StorageError + '_ {
    move |source| StorageError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// Reads and checks a constants file (format in `docs/files.md`). Parse errors and validation
/// errors are both refusals.
pub fn load_constants(path: &Path) -> Result<Constants, StorageError> {
    let text = fs::read_to_string(path).map_err(io_err(path))?;
    let invalid = |diagnostics| StorageError::Invalid {
        path: path.to_path_buf(),
        diagnostics,
    };
    let c = Constants::parse(&text).map_err(invalid)?;
    let errs = c.validate();
    if errs.is_empty() {
        Ok(c)
    } else {
        Err(invalid(errs))
    }
}

/// Writes the constants file atomically (only constants that were set, see
/// [`Constants::to_text`]). Refuses constants that do not validate.
pub fn save_constants(path: &Path, c: &Constants) -> Result<(), StorageError> {
    let errs = c.validate();
    if !errs.is_empty() {
        return Err(StorageError::Invalid {
            path: path.to_path_buf(),
            diagnostics: errs,
        });
    }
    write_atomic(path, c.to_text().as_bytes()).map_err(io_err(path))
}

/// The offset table TAB0.KOR: the file and the memory copy the controller works with (SPEC §3).
///
/// - power-on / [`OffsetStore::load`]: the file is read into memory;
/// - (a) [`OffsetStore::save_file_text`]: an edited file is saved; memory becomes the file's
///   table (values written by G92 are replaced, as in the manual);
/// - (b) [`OffsetStore::operator_edit`]: an operator edit goes to the file **and** memory;
/// - (c) [`OffsetStore::program_write`]: `G92` writes memory only.
///
/// Every call is all-or-nothing: a refused text or value, or a failed disk write, changes
/// neither the file nor memory.
#[derive(Debug)]
pub struct OffsetStore {
    path: PathBuf,
    axis_names: Vec<char>,
    file: KorFile,
    memory: OffsetTable,
}

impl OffsetStore {
    /// Power-on: reads the file into memory.
    pub fn load(path: impl Into<PathBuf>, axis_names: &[char]) -> Result<Self, StorageError> {
        let path = path.into();
        let text = fs::read_to_string(&path).map_err(io_err(&path))?;
        let file =
            offsets::parse(&text, axis_names).map_err(|diagnostics| StorageError::Invalid {
                path: path.clone(),
                diagnostics,
            })?;
        Ok(OffsetStore {
            memory: file.table.clone(),
            path,
            axis_names: axis_names.to_vec(),
            file,
        })
    }

    /// Power-on when the file may not exist yet: a missing file is an empty (all zero) table
    /// and is created on the first save or operator edit.
    pub fn load_or_empty(
        path: impl Into<PathBuf>,
        axis_names: &[char],
    ) -> Result<Self, StorageError> {
        let path = path.into();
        match fs::metadata(&path) {
            Err(e) if e.kind() == io::ErrorKind::NotFound => Ok(OffsetStore {
                path,
                axis_names: axis_names.to_vec(),
                file: KorFile::default(),
                memory: OffsetTable::new(),
            }),
            _ => Self::load(path, axis_names),
        }
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The table the controller works with (the interpreter's `Setup::offsets` at program start).
    pub fn memory(&self) -> &OffsetTable {
        &self.memory
    }

    /// The table as it is in the file.
    pub fn file(&self) -> &KorFile {
        &self.file
    }

    /// The file's text as it would be written now (for the editor).
    pub fn file_text(&self) -> String {
        offsets::write(&self.file, &self.axis_names)
    }

    /// (a) Saves an edited file: checked, written atomically, then memory = file.
    pub fn save_file_text(&mut self, text: &str) -> Result<(), StorageError> {
        let file = offsets::parse(text, &self.axis_names).map_err(|diagnostics| {
            StorageError::Invalid {
                path: self.path.clone(),
                diagnostics,
            }
        })?;
        write_atomic(&self.path, text.as_bytes()).map_err(io_err(&self.path))?;
        self.memory = file.table.clone();
        self.file = file;
        Ok(())
    }

    /// (b) Operator edit of one entry: the values present change in the file and in memory.
    pub fn operator_edit(&mut self, edit: &TableEdit) -> Result<(), StorageError> {
        let refuse = |e: offsets::OffsetError| StorageError::Invalid {
            path: self.path.clone(),
            diagnostics: vec![Diagnostic::error(e.code(), None, 0, 0, e.to_string())],
        };
        let mut file = self.file.clone();
        file.table.apply(edit).map_err(refuse)?;
        let mut memory = self.memory.clone();
        memory.apply(edit).map_err(refuse)?;
        let text = offsets::write(&file, &self.axis_names);
        write_atomic(&self.path, text.as_bytes()).map_err(io_err(&self.path))?;
        self.file = file;
        self.memory = memory;
        Ok(())
    }

    /// (b) Operator edit written like a file line, e.g. `12: R=5.0 Z=-3`.
    pub fn operator_edit_text(&mut self, line: &str) -> Result<(), StorageError> {
        let edit =
            offsets::parse_edit(line, &self.axis_names).map_err(|d| StorageError::Invalid {
                path: self.path.clone(),
                diagnostics: vec![d],
            })?;
        self.operator_edit(&edit)
    }

    /// (c) `G92 D<n> R0..R4` executed (a `BlockKind::TableWrite`): memory only.
    pub fn program_write(&mut self, edit: &TableEdit) -> Result<(), offsets::OffsetError> {
        self.memory.apply(edit)
    }
}
