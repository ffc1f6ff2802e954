//! Daemon configuration: one TOML file. Every key has a default, so an empty file (or none)
//! gives the built-in simulated 3-axis mill.
//!
//! One file per section of the TOML file, each with the section's types, defaults and checks;
//! this file holds the whole [`Config`], its loading and the one [`Config::validate`] that
//! calls the sections' checks in order.
//!
//! Adding a section `[foo]`: write `foo.rs` with its struct (`#[serde(deny_unknown_fields)]`,
//! a `Default` that matches the serde defaults, so a file without the section keeps working)
//! and `pub fn validate(&self) -> Result<(), InvalidConfig>` naming keys as `foo.key`; then
//! add `mod foo;` and its `pub use` below, a `#[serde(default)] pub foo: FooSection` field
//! and its default in [`Config`], and a call in [`Config::validate`] (at the end, so the
//! existing sections' mistakes are still the first reported).
//!
//! The section structs mirror their TOML tables key by key, so some have many fields (`[[axes]]`,
//! `[api]`, `[bus]`): grouping keys into sub-structs would need `#[serde(flatten)]`, which serde
//! does not support together with `deny_unknown_fields`, the check that names a mistyped key.

mod api;
mod axes;
mod bus;
mod error;
mod hmi;
mod io;
mod io_check;
mod kr;
mod mtconnect;
mod planner;
mod probe;
mod program;
mod rt;
mod sim;
mod storage;
mod tool_change;

use std::path::Path;

use serde::Deserialize;

pub use api::{ApiConfig, Role, TokenConfig};
pub use axes::{AxisConfig, HomingMode};
pub use bus::{BusConfig, CanBusConfig, FaultReactionKey, SerialBusConfig, ShutdownKey};
pub use error::{ConfigError, InvalidConfig};
pub use hmi::{HmiSection, HmiTlsFiles};
pub use io::{
    AlarmSeverity, InputConfig, InputFunction, IoSection, ModuleConfig, OutputConfig,
    OutputFunction, RESERVED_M, Wiring, parse_m,
};
pub use io_check::IoContext;
pub use kr::{GearConfig, KrSection, RadiusInputConfig};
pub use mtconnect::MtconnectConfig;
pub use planner::PlannerSection;
pub use probe::{ProbeSection, SetterConfig};
pub use program::{IjSetting, ProgramSection};
pub use rt::RtConfig;
pub use sim::{SimConfig, SimCylinderConfig};
pub use storage::StorageConfig;
pub use tool_change::{ToolChangeMode, ToolChangeSection};

/// The whole file: one field per TOML section, each section its own type and file.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Config {
    /// Machine axes in machine order (R0..R5).
    #[serde(default = "axes::default_axes")]
    pub axes: Vec<AxisConfig>,
    #[serde(default)]
    pub bus: BusConfig,
    #[serde(default)]
    pub api: ApiConfig,
    #[serde(default)]
    pub rt: RtConfig,
    #[serde(default)]
    pub sim: SimConfig,
    #[serde(default)]
    pub storage: StorageConfig,
    #[serde(default)]
    pub kr: KrSection,
    #[serde(default)]
    pub program: ProgramSection,
    #[serde(default)]
    pub planner: PlannerSection,
    #[serde(default)]
    pub hmi: HmiSection,
    /// The MTConnect agent (docs/mtconnect.md).
    #[serde(default)]
    pub mtconnect: MtconnectConfig,
    /// Digital inputs and outputs (docs/io.md); unset: the simulated machine's own set on
    /// `[bus] kind = "sim"`, none on a real bus ([`Config::io`]).
    #[serde(default)]
    pub io: Option<IoSection>,
    /// `[tool_change]`: what M6 does (docs/setup.md).
    #[serde(default)]
    pub tool_change: ToolChangeSection,
    /// `[probe]`: probing feeds and the tool setter (docs/setup.md); [`Config::probe`].
    #[serde(default)]
    pub probe: ProbeSection,
}

impl Default for Config {
    fn default() -> Self {
        Config {
            axes: axes::default_axes(),
            bus: BusConfig::default(),
            api: ApiConfig::default(),
            rt: RtConfig::default(),
            sim: SimConfig::default(),
            storage: StorageConfig::default(),
            kr: KrSection::default(),
            program: ProgramSection::default(),
            planner: PlannerSection::default(),
            hmi: HmiSection::default(),
            mtconnect: MtconnectConfig::default(),
            io: None,
            tool_change: ToolChangeSection::default(),
            probe: ProbeSection::default(),
        }
    }
}

impl Config {
    pub fn load(path: &Path) -> Result<Config, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Read {
            path: path.to_owned(),
            source,
        })?;
        Self::parse(&text, path)
    }

    /// Parses and validates a configuration text; `path` is used in messages.
    pub fn parse(text: &str, path: &Path) -> Result<Config, ConfigError> {
        let cfg: Config = toml::from_str(text).map_err(|e| ConfigError::Parse {
            path: path.to_owned(),
            message: e.to_string(),
        })?;
        cfg.validate().map_err(|source| ConfigError::Invalid {
            path: path.to_owned(),
            source,
        })?;
        Ok(cfg)
    }

    /// Fuzzing entry of the configuration door (`fuzz/`, issue #50): arbitrary bytes as a
    /// `cncd.toml`, through the path `--check-config` and start-up take (parse, validate),
    /// then what start-up derives from a valid file. Must never panic; an error has a code
    /// and a message.
    pub fn fuzz_entry(data: &[u8]) {
        let text = String::from_utf8_lossy(data);
        match Config::parse(&text, Path::new("fuzz.toml")) {
            Ok(c) => {
                let _ = c.axis_names();
                let _ = c.probe();
                let _ = crate::runtime::buses::IoWiring::of(&c);
            }
            Err(e) => assert!(!e.code().is_empty() && !e.to_string().is_empty()),
        }
    }

    /// Checks what serde cannot: counts, ranges, duplicates. The message names the key. The
    /// order is the order mistakes are reported in (the first one found).
    pub fn validate(&self) -> Result<(), InvalidConfig> {
        axes::validate(&self.axes)?;
        self.kr.validate()?;
        self.storage.validate()?;
        axes::validate_positions(&self.axes)?;
        self.sim.validate()?;
        self.probe.validate()?;
        self.planner.validate()?;
        self.rt.validate()?;
        self.api.validate()?;
        self.bus.validate(&self.axes)?;
        self.hmi.validate(&self.api)?;
        let tls = self.api.tls_cert.is_some() && self.api.tls_key.is_some();
        self.mtconnect.validate(tls)?;
        self.io().validate(&IoContext {
            bus: &self.bus,
            axes: &self.axes,
            gear_m: self.kr.gears.iter().filter_map(|g| g.m_code).collect(),
        })?;
        self.tool_change.validate(&self.io())?;
        self.program.validate()
    }

    /// The machine's inputs and outputs: the `[io]` section, or without one the simulated
    /// machine's own set (`[bus] kind = "sim"`) or none.
    pub fn io(&self) -> IoSection {
        match (&self.io, &self.bus) {
            (Some(io), _) => io.clone(),
            (None, BusConfig::Sim { .. }) => IoSection::sim_default(&self.axes),
            (None, _) => IoSection::default(),
        }
    }

    /// The probing settings; on the simulated machine the setter defaults to its simulated
    /// one.
    pub fn probe(&self) -> ProbeSection {
        let mut p = self.probe.clone();
        if let (None, BusConfig::Sim { .. }) = (&p.setter, &self.bus) {
            let s = sim::default_setter();
            p.setter = Some(SetterConfig {
                x_mm: s.x_mm,
                y_mm: s.y_mm,
                z_mm: s.top_mm,
                clearance_z_mm: 0.0,
            });
        }
        p
    }

    pub fn axis_names(&self) -> Vec<char> {
        self.axes.iter().map(|a| a.name).collect()
    }

    /// The soft limits of every axis (issue #15); unset sides are unlimited.
    pub fn soft_limits(&self) -> kernel::limits::SoftLimits {
        let mut l = kernel::limits::SoftLimits::NONE;
        for (i, a) in self.axes.iter().enumerate().take(kernel::MAX_AXES) {
            l.min_mm[i] = a.soft_min_mm.unwrap_or(f64::NEG_INFINITY);
            l.max_mm[i] = a.soft_max_mm.unwrap_or(f64::INFINITY);
        }
        l
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn empty_file_is_the_simulated_mill() {
        let c = Config::parse("", Path::new("x.toml")).unwrap();
        assert_eq!(c.axis_names(), ['X', 'Y', 'Z']);
        assert_eq!(c.api.listen.port(), 50051);
    }

    #[test]
    fn mistakes_name_the_key() {
        let e = Config::parse(
            "[[axes]]\nname = 'X'\nmax_accel_mm_s2 = -1\n",
            Path::new("m.toml"),
        )
        .unwrap_err();
        assert!(e.to_string().contains("axes[0].max_accel_mm_s2"), "{e}");
        let ConfigError::Invalid { source, .. } = &e else {
            panic!("{e}")
        };
        assert_eq!(
            (source.code(), source.key()),
            ("config_bad_value", "axes[0].max_accel_mm_s2")
        );
        let mut twice = Config::default();
        twice.axes[1].name = twice.axes[0].name;
        let e = twice.validate().unwrap_err();
        assert_eq!((e.code(), e.key()), ("config_duplicate", "axes[1].name"));
        let mut half_tls = Config::default();
        half_tls.api.tls_cert = Some("cert.pem".into());
        let e = half_tls.validate().unwrap_err();
        assert_eq!(e.code(), "config_missing");
        let e = Config::parse("[api]\nlisten = 5\n", Path::new("m.toml")).unwrap_err();
        assert!(e.to_string().contains("listen"), "{e}");
        let e = Config::parse("[rt]\nprio = 5\n", Path::new("m.toml")).unwrap_err();
        assert!(e.to_string().contains("prio"), "{e}");
    }

    // SPEC §2: I J relative (default) or absolute, a setting.
    #[test]
    fn program_ij_setting() {
        let c = Config::parse("", Path::new("x.toml")).unwrap();
        assert_eq!(c.program.ij, IjSetting::Relative);
        let c = Config::parse("[program]\nij = \"absolute\"\n", Path::new("x.toml")).unwrap();
        assert_eq!(
            kernel::program::IjMode::from(c.program.ij),
            kernel::program::IjMode::Absolute
        );
        let e =
            Config::parse("[program]\nij = \"incremental\"\n", Path::new("m.toml")).unwrap_err();
        assert!(e.to_string().contains("ij"), "{e}");
    }

    #[test]
    fn program_dialect_setting() {
        use kernel::program::Dialect;
        let c = Config::parse("", Path::new("x.toml")).unwrap();
        assert_eq!(c.program.dialect(), Dialect::Cnc836);
        let c = Config::parse("[program]\ndialect = \"iso\"\n", Path::new("x.toml")).unwrap();
        assert_eq!(c.program.dialect(), Dialect::Iso);
        let e = Config::parse("[program]\ndialect = \"fanuc\"\n", Path::new("m.toml")).unwrap_err();
        let ConfigError::Invalid { source, .. } = &e else {
            panic!("{e}")
        };
        assert_eq!(
            (source.code(), source.key()),
            ("config_bad_value", "program.dialect")
        );
        assert!(e.to_string().contains("\"cnc836\" or \"iso\""), "{e}");
    }
}
