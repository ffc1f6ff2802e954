//! Start-up: the data files loaded and checked against the configuration, and what the RT
//! core and every job's machine setup are built from. Shared with the simulation harness, so
//! both start the same machine.

use kernel::constants::{AXIS_CODES, Constants};
use kernel::kr::{Gear, Kr, RadiusInput};
use kernel::machine::{AxisLimits, MachineConfig, MachineSetup};
use kernel::offsets::OffsetTable;
use kernel::units::{AxesMm, MAX_AXES};

use crate::runtime::config::{Config, RadiusInputConfig};
use crate::runtime::rt::RtCoreConfig;
use crate::runtime::storage::{self, ConstantsFile, OffsetStore, WorkOffsetStore};

/// Why the controller did not start (the message names the key or file to fix).
#[derive(Debug, thiserror::Error)]
pub enum StartError {
    /// The bus could not be opened (`open_bus`: the message names the interface or port).
    #[error(transparent)]
    Bus(#[from] crate::runtime::buses::OpenBusError),
    #[error("storage.dir: cannot create {}: {source}", dir.display())]
    StorageDir {
        dir: std::path::PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The constants or offsets file exists but does not load.
    #[error(transparent)]
    Storage(#[from] storage::StorageError),
    #[error("{}: R0..R5 name the axes {named} but the configuration has {configured}", path.display())]
    AxisNames {
        path: std::path::PathBuf,
        named: String,
        configured: String,
    },
    #[error("constant cutting speed: {0}")]
    Kr(#[from] kernel::kr::KrConfigError),
    #[error("cannot start the real-time thread: {0}")]
    RtThread(#[source] std::io::Error),
    #[error("cannot start the status thread: {0}")]
    StatusThread(#[source] std::io::Error),
}

impl StartError {
    /// Stable code (tests and logs match it; the message may improve).
    pub fn code(&self) -> &'static str {
        match self {
            StartError::Bus(_) => "start_bus",
            StartError::StorageDir { .. } => "start_storage_dir",
            StartError::Storage(e) => e.code(),
            StartError::AxisNames { .. } => "start_axis_names",
            StartError::Kr(_) => "start_kr",
            StartError::RtThread(_) => "start_rt_thread",
            StartError::StatusThread(_) => "start_status_thread",
        }
    }
}

/// Fault-reaction deceleration of each axis (`stop_decel_mm_s2`, else its acceleration).
fn stop_decel(config: &Config) -> [f64; MAX_AXES] {
    let mut d = [f64::INFINITY; MAX_AXES];
    for (i, a) in config.axes.iter().enumerate().take(MAX_AXES) {
        d[i] = a.stop_decel();
    }
    d
}

/// What the RT core is built from: the axes at their home positions, KŘR and the G24 window
/// of the machine setup at start-up (each job's Start brings its own, see
/// [`crate::runtime::rt::JobMachine`]).
pub(crate) fn rt_core_config(
    config: &Config,
    constants: &(Constants, bool),
    offsets: &OffsetTable,
) -> Result<RtCoreConfig, StartError> {
    let mut start = AxesMm::ZERO;
    for (i, a) in config.axes.iter().enumerate() {
        start[i] = a.home_mm;
    }
    let setup = MachineSetup::new(
        &machine_config(config),
        &constants.0,
        constants.1,
        offsets,
        start,
    )?;
    Ok(RtCoreConfig {
        axes: config.axes.len(),
        start,
        kr: Kr::new(setup.kr().cloned().expect("the daemon's setup has KŘR")),
        in_position_mm: setup.in_position_mm(),
        stop_decel_mm_s2: stop_decel(config),
        cycle_ns: config.bus.cycle_ns(),
        io: crate::runtime::io_setup::functions(config),
        tool_changer: crate::runtime::io_setup::tool_changer(config),
    })
}

/// The configuration's part of the machine setup: axis limits, gear table, radius input.
pub(crate) fn machine_config(config: &Config) -> MachineConfig {
    let radius_input = match config.kr.radius_input {
        RadiusInputConfig::Diameter => RadiusInput::Diameter,
        RadiusInputConfig::Radius => RadiusInput::Radius,
    };
    MachineConfig {
        axes: config
            .axes
            .iter()
            .map(|a| AxisLimits {
                name: a.name,
                max_velocity_mm_min: a.max_velocity_mm_min,
                max_accel_mm_s2: a.max_accel_mm_s2,
            })
            .collect(),
        m_outputs: crate::runtime::io_setup::m_functions(config),
        tool_number_bits: crate::runtime::io_setup::tool_number_bits(config),
        gears: config
            .kr
            .gears
            .iter()
            .map(|g| Gear {
                max_rpm: g.max_rpm,
                output_range: g.output_range,
                m_code: g.m_code,
            })
            .collect(),
        radius_input,
        rotary_pulses_per_rev: config
            .axes
            .iter()
            .map(|a| a.rotary_pulses_per_rev)
            .collect(),
        ij: config.program.ij.into(),
        encoding: config.program.encoding.into(),
        dialect: config.program.dialect(),
        preprocessor: true,
        min_block_time_s: config.planner.min_block_time_ms / 1000.0,
        soft_limits: config.soft_limits(),
    }
}

/// The data files as start-up loaded them.
pub(crate) struct LoadedStorage {
    /// The constants, and whether they came from a file.
    pub constants: (Constants, bool),
    pub offsets: OffsetStore,
    pub constants_file: ConstantsFile,
    /// Work offsets G54..G59.3 (ISO programs).
    pub work: WorkOffsetStore,
}

/// Creates the data directory and loads the constants, the offset table and the work offsets.
/// A file that exists but does not parse stops the start-up: running with wrong offsets
/// scraps parts.
pub(crate) fn load_storage(config: &Config) -> Result<LoadedStorage, StartError> {
    let st = &config.storage;
    std::fs::create_dir_all(&st.dir).map_err(|source| StartError::StorageDir {
        dir: st.dir.clone(),
        source,
    })?;
    let cpath = st.constants_path();
    let names = config.axis_names();
    let (constants_file, from_file) = ConstantsFile::open(&cpath)?;
    let constants = if let Some(c) = from_file {
        // R0..R5 name the axes the programs use: they must be the configured ones.
        let named = c.axis_names();
        if named[..] != names[..] {
            return Err(StartError::AxisNames {
                path: cpath,
                named: named.iter().collect(),
                configured: names.iter().collect(),
            });
        }
        (c, true)
    } else {
        // Defaults, with the axes of the configuration in R0..R5.
        let mut c = Constants::new();
        for r in 0..6u16 {
            let code = names
                .get(r as usize)
                .and_then(|n| AXIS_CODES.iter().position(|a| a == n))
                .map_or(0.0, |k| (k + 1) as f64);
            c.set(r, code);
        }
        (c, false)
    };
    let offsets = OffsetStore::load_or_empty(st.offsets_path(), &names)?;
    let work = WorkOffsetStore::load_or_empty(st.work_offsets_path(), &names)?;
    tracing::info!(
        constants = %cpath.display(),
        from_file = constants.1,
        offsets = %st.offsets_path().display(),
        work_offsets = %st.work_offsets_path().display(),
        "data files loaded"
    );
    Ok(LoadedStorage {
        constants,
        offsets,
        constants_file,
        work,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A start-up that cannot use its storage says why, with a code per cause.
    #[test]
    fn storage_refusals_at_start_have_codes() {
        let base = std::env::temp_dir().join(format!("cnc-start-{}", std::process::id()));
        std::fs::create_dir_all(&base).unwrap();
        let mut config = Config::default();
        // The data directory is a file: it cannot be created.
        let file = base.join("plain-file");
        std::fs::write(&file, "x").unwrap();
        config.storage.dir = file;
        let e = load_storage(&config).err().unwrap();
        assert_eq!(e.code(), "start_storage_dir", "{e}");
        // An offset table that does not parse stops the start-up.
        config.storage.dir = base.join("data");
        std::fs::create_dir_all(&config.storage.dir).unwrap();
        std::fs::write(config.storage.offsets_path(), "not an offset table\n").unwrap();
        let e = load_storage(&config).err().unwrap();
        assert_eq!(e.code(), "storage_invalid", "{e}");
        // So does a work offsets file that does not parse.
        std::fs::remove_file(config.storage.offsets_path()).unwrap();
        std::fs::write(config.storage.work_offsets_path(), "G54 X1\nG54 Y2\n").unwrap();
        let e = load_storage(&config).err().unwrap();
        assert_eq!(e.code(), "storage_invalid", "{e}");
        assert!(e.to_string().contains("G54 is listed twice"), "{e}");
        std::fs::remove_dir_all(&base).unwrap();
    }
}
