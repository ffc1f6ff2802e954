//! `[storage]`: where the controller keeps its data files.

use std::path::PathBuf;

use serde::Deserialize;

use super::InvalidConfig;

/// Where the controller keeps its data files.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct StorageConfig {
    /// Directory of the data files (systemd: the unit's StateDirectory, `/var/lib/cncd`).
    /// Relative paths are taken from the daemon's working directory.
    #[serde(default = "default_storage_dir")]
    pub dir: PathBuf,
    /// Offset table file (SPEC §3; `$21` of CNC836.KNF), relative to `dir`.
    #[serde(default = "default_offsets_file")]
    pub offsets_file: PathBuf,
    /// Machine constants file (`Rnnn=value` lines, see docs/files.md), relative to `dir`. A
    /// missing file means every constant at its default.
    #[serde(default = "default_constants_file")]
    pub constants_file: PathBuf,
    /// Work offsets G54..G59.3 of ISO programs (docs/files.md), relative to `dir`; created
    /// on the first edit (missing: every offset 0).
    #[serde(default = "default_work_offsets_file")]
    pub work_offsets_file: PathBuf,
    /// Program library directory (stored programs, survive restarts), relative to `dir`.
    #[serde(default = "default_programs_dir")]
    pub programs_dir: PathBuf,
    /// Most bytes the program library may hold (RESOURCE_EXHAUSTED beyond).
    #[serde(default = "default_programs_max_bytes")]
    pub programs_max_bytes: u64,
}

fn default_storage_dir() -> PathBuf {
    PathBuf::from("cncd-data")
}
fn default_offsets_file() -> PathBuf {
    PathBuf::from("TAB0.KOR")
}
fn default_constants_file() -> PathBuf {
    PathBuf::from("TAB0.REK")
}
fn default_work_offsets_file() -> PathBuf {
    PathBuf::from("WORK.OFS")
}
fn default_programs_dir() -> PathBuf {
    PathBuf::from("programs")
}
fn default_programs_max_bytes() -> u64 {
    2 << 30
}

impl Default for StorageConfig {
    fn default() -> Self {
        StorageConfig {
            dir: default_storage_dir(),
            offsets_file: default_offsets_file(),
            constants_file: default_constants_file(),
            work_offsets_file: default_work_offsets_file(),
            programs_dir: default_programs_dir(),
            programs_max_bytes: default_programs_max_bytes(),
        }
    }
}

impl StorageConfig {
    pub fn offsets_path(&self) -> PathBuf {
        self.dir.join(&self.offsets_file)
    }
    pub fn constants_path(&self) -> PathBuf {
        self.dir.join(&self.constants_file)
    }
    pub fn work_offsets_path(&self) -> PathBuf {
        self.dir.join(&self.work_offsets_file)
    }
    pub fn programs_path(&self) -> PathBuf {
        self.dir.join(&self.programs_dir)
    }

    /// `[storage]`: a directory and three different files.
    pub fn validate(&self) -> Result<(), InvalidConfig> {
        if self.dir.as_os_str().is_empty() {
            return Err(InvalidConfig::Missing {
                key: "storage.dir".into(),
                detail: "must name a directory".into(),
            });
        }
        let files = [
            ("storage.offsets_file", &self.offsets_file),
            ("storage.constants_file", &self.constants_file),
            ("storage.work_offsets_file", &self.work_offsets_file),
        ];
        for (key, f) in files {
            if f.file_name().is_none() {
                return Err(InvalidConfig::Missing {
                    key: key.to_string(),
                    detail: format!("{f:?} must name a file"),
                });
            }
        }
        for (i, (key, f)) in files.iter().enumerate() {
            if let Some((earlier, _)) = files[..i]
                .iter()
                .find(|(_, g)| self.dir.join(g) == self.dir.join(f))
            {
                return Err(InvalidConfig::Duplicate {
                    key: key.to_string(),
                    detail: format!("the same file as {earlier}"),
                });
            }
        }
        Ok(())
    }
}
