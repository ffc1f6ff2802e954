//! Command line and fault-injection commands shared by the simulator binaries.
//!
//! Fault injection is driven by lines on the simulator's standard input, so a test (or a
//! person at a terminal) can switch faults on and off while it runs:
//!
//! | line | effect |
//! |---|---|
//! | `heartbeat off [NODE]` / `heartbeat on [NODE]` | stop / resume heartbeats (CAN) |
//! | `silent on [NODE]` / `silent off [NODE]` | stop answering anything / resume |
//! | `corrupt on [NODE]` / `corrupt off [NODE]` | send corrupt frames (CAN: short TPDO; serial: bit flip) |
//! | `fault CODE [NODE]` | force a drive fault with error code CODE (hex, e.g. `2310`) |
//! | `unplug` / `plug` | close the serial line / open a new one at the same link path (serial) |
//! | `state` | print each node's state (CAN: NMT state, statusword, error code, 0x1016:1) |
//! | `input NODE BIT 0\|1` | set input BIT of CAN node NODE: a module's 0x6000 bit (group BIT / 8 + 1), a drive's 0x60FD bit |
//! | `outputs NODE` | print `outputs node NODE XXXXXXXXXXXXXXXX`: a module's 0x6200 groups (group 1 lowest), a drive's 0x60FE:1 |
//! | `quit` | exit |
//!
//! NODE is a CAN node id, or a 1-based axis number for the serial unit; without it the
//! command applies to all.

use std::io::BufRead;
use std::sync::mpsc;

use crate::SimDriveParams;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Command {
    Heartbeat(bool, Option<u8>),
    Silent(bool, Option<u8>),
    Corrupt(bool, Option<u8>),
    Fault(u16, Option<u8>),
    Unplug,
    Plug,
    /// Print each node's state on stdout (CAN: `state node N nmt .. statusword .. error ..
    /// consumer ..`).
    State,
    /// Sets input `bit` of CAN node `node` (an I/O module's 0x6000, a drive's 0x60FD).
    Input {
        node: u8,
        bit: u8,
        on: bool,
    },
    /// Prints the outputs of CAN node `node` (an I/O module's 0x6200, a drive's 0x60FE:1).
    Outputs(u8),
    Quit,
}

/// Why a fault-injection line was not understood.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum CommandError {
    #[error("expected on or off")]
    ExpectedOnOff,
    #[error("bad node '{0}'")]
    BadNode(String),
    #[error("expected a hex error code")]
    ExpectedHexCode,
    #[error("expected NODE BIT 0|1")]
    ExpectedInput,
    #[error("unknown command '{0}'")]
    Unknown(String),
}

impl CommandError {
    /// Stable code (tests match it; the message may improve).
    pub fn code(&self) -> &'static str {
        match self {
            CommandError::ExpectedOnOff => "sim_expected_on_off",
            CommandError::BadNode(_) => "sim_bad_node",
            CommandError::ExpectedHexCode => "sim_expected_hex_code",
            CommandError::ExpectedInput => "sim_expected_input",
            CommandError::Unknown(_) => "sim_unknown_command",
        }
    }
}

fn on_off(w: Option<&str>) -> Result<bool, CommandError> {
    match w {
        Some("on") => Ok(true),
        Some("off") => Ok(false),
        _ => Err(CommandError::ExpectedOnOff),
    }
}

fn node(w: Option<&str>) -> Result<Option<u8>, CommandError> {
    w.map(|s| s.parse().map_err(|_| CommandError::BadNode(s.to_string())))
        .transpose()
}

pub fn parse(line: &str) -> Result<Command, CommandError> {
    let mut w = line.split_whitespace();
    let cmd = w.next().unwrap_or("");
    let a = w.next();
    let b = w.next();
    Ok(match cmd {
        "heartbeat" => Command::Heartbeat(on_off(a)?, node(b)?),
        "silent" => Command::Silent(on_off(a)?, node(b)?),
        "corrupt" => Command::Corrupt(on_off(a)?, node(b)?),
        "fault" => {
            let code = a
                .and_then(|s| u16::from_str_radix(s.trim_end_matches('h'), 16).ok())
                .ok_or(CommandError::ExpectedHexCode)?;
            Command::Fault(code, node(b)?)
        }
        "unplug" => Command::Unplug,
        "plug" => Command::Plug,
        "state" => Command::State,
        "input" => {
            let value = match w.next() {
                Some("1") => true,
                Some("0") => false,
                _ => return Err(CommandError::ExpectedInput),
            };
            let number = |s: Option<&str>| s.and_then(|s| s.parse::<u8>().ok());
            match (number(a), number(b)) {
                (Some(node), Some(bit)) if bit < 64 => Command::Input {
                    node,
                    bit,
                    on: value,
                },
                _ => return Err(CommandError::ExpectedInput),
            }
        }
        "outputs" => match node(a)? {
            Some(n) => Command::Outputs(n),
            None => return Err(CommandError::BadNode(String::new())),
        },
        "quit" => Command::Quit,
        _ => return Err(CommandError::Unknown(cmd.to_string())),
    })
}

/// Reads commands from stdin on a thread. End of input is not a command: the simulator keeps
/// running until killed or told `quit`.
pub fn stdin_commands() -> mpsc::Receiver<Command> {
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        for line in std::io::stdin().lock().lines() {
            let Ok(line) = line else { return };
            if line.trim().is_empty() {
                continue;
            }
            match parse(&line) {
                Ok(c) => {
                    if tx.send(c).is_err() {
                        return;
                    }
                }
                Err(e) => eprintln!("sim: {e}"),
            }
        }
    });
    rx
}

/// Options common to the simulators.
#[derive(Clone, Debug, PartialEq)]
pub struct SimArgs {
    /// CAN interface (`sim-can`).
    pub iface: String,
    /// Node ids (`sim-can`), one drive each.
    pub nodes: Vec<u8>,
    /// Node ids of CiA 401 I/O modules (`sim-can`).
    pub io_modules: Vec<u8>,
    /// 8-bit groups of inputs and of outputs each module has (1..=8).
    pub io_groups: u8,
    /// Link path (`sim-serial`): a symlink to the pty the controller opens.
    pub link: String,
    /// Axes of the serial unit.
    pub axes: usize,
    pub increments_per_mm: f64,
    pub start_mm: f64,
    pub params: SimDriveParams,
    /// Velocity units per rpm of a drive run in velocity mode (a spindle: CAN nodes the master
    /// puts in CSV, the serial unit's spindle).
    pub units_per_rpm: f64,
    /// Acceleration of a spindle, rpm/s (0: it reaches the setpoint at once).
    pub ramp_rpm_s: f64,
    /// The serial unit has a spindle drive (protocol version 2).
    pub spindle: bool,
    /// Edge of the home switch of each drive in its power-on coordinates, mm (CiA 402 homing
    /// mode, [`crate::homing`]); `None`: no switch.
    pub home_switch_mm: Option<f64>,
}

pub const USAGE: &str = "options: --iface IF --node N (repeatable) --io-module N (repeatable) \
    --io-groups N | --link PATH --axes N \
    [--spindle]; --increments-per-mm F --start-mm F --kv F --v-max-mm-s F --window-mm F \
    --units-per-rpm F --ramp-rpm-s F --home-switch-mm F";

/// Why the simulator's command line was refused (each message ends the simulator).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ArgsError {
    #[error("{0} needs a value")]
    MissingValue(String),
    #[error("bad number '{0}'")]
    BadNumber(String),
    #[error("bad node id '{0}'")]
    BadNodeId(String),
    #[error("node id {0} outside 1..127")]
    NodeIdRange(u8),
    #[error("bad axis count '{0}'")]
    BadAxisCount(String),
    /// `-h`/`--help`: the message is the usage.
    #[error("{}", USAGE)]
    Help,
    #[error("unknown option '{0}'; {usage}", usage = USAGE)]
    UnknownOption(String),
    #[error("--units-per-rpm must be positive and --ramp-rpm-s not negative")]
    SpindleRange,
    #[error("bad group count '{0}' (1..8)")]
    BadGroups(String),
}

impl ArgsError {
    /// Stable code (tests match it; the message may improve).
    pub fn code(&self) -> &'static str {
        match self {
            ArgsError::MissingValue(_) => "sim_missing_value",
            ArgsError::BadNumber(_) => "sim_bad_number",
            ArgsError::BadNodeId(_) => "sim_bad_node_id",
            ArgsError::NodeIdRange(_) => "sim_node_id_range",
            ArgsError::BadAxisCount(_) => "sim_bad_axis_count",
            ArgsError::Help => "sim_help",
            ArgsError::UnknownOption(_) => "sim_unknown_option",
            ArgsError::SpindleRange => "sim_spindle_range",
            ArgsError::BadGroups(_) => "sim_bad_groups",
        }
    }
}

/// A node id option's value, 1..=127.
fn node_id(s: String) -> Result<u8, ArgsError> {
    let n: u8 = s.parse().map_err(|_| ArgsError::BadNodeId(s))?;
    if !(1..=127).contains(&n) {
        return Err(ArgsError::NodeIdRange(n));
    }
    Ok(n)
}

impl SimArgs {
    pub fn parse(args: impl Iterator<Item = String>) -> Result<SimArgs, ArgsError> {
        let mut a = SimArgs {
            iface: "vcan0".into(),
            nodes: Vec::new(),
            io_modules: Vec::new(),
            io_groups: 8,
            link: String::new(),
            axes: 1,
            increments_per_mm: 10_000.0,
            start_mm: 0.0,
            params: SimDriveParams::default(),
            units_per_rpm: 1.0,
            ramp_rpm_s: 2000.0,
            spindle: false,
            home_switch_mm: None,
        };
        let mut it = args;
        while let Some(k) = it.next() {
            let mut v = || it.next().ok_or_else(|| ArgsError::MissingValue(k.clone()));
            let num = |s: String| s.parse::<f64>().map_err(|_| ArgsError::BadNumber(s));
            match k.as_str() {
                "--iface" => a.iface = v()?,
                "--node" => a.nodes.push(node_id(v()?)?),
                "--io-module" => a.io_modules.push(node_id(v()?)?),
                "--io-groups" => {
                    let s = v()?;
                    a.io_groups = s
                        .parse()
                        .ok()
                        .filter(|n| (1..=8).contains(n))
                        .ok_or(ArgsError::BadGroups(s))?;
                }
                "--link" => a.link = v()?,
                "--axes" => {
                    let s = v()?;
                    a.axes = s
                        .parse()
                        .ok()
                        .filter(|n| (1..=hal::MAX_AXES).contains(n))
                        .ok_or(ArgsError::BadAxisCount(s))?;
                }
                "--increments-per-mm" => a.increments_per_mm = num(v()?)?,
                "--start-mm" => a.start_mm = num(v()?)?,
                "--kv" => a.params.kv_per_s = num(v()?)?,
                "--v-max-mm-s" => a.params.v_max_mm_s = num(v()?)?,
                "--window-mm" => a.params.following_window_mm = num(v()?)?,
                "--units-per-rpm" => a.units_per_rpm = num(v()?)?,
                "--ramp-rpm-s" => a.ramp_rpm_s = num(v()?)?,
                "--spindle" => a.spindle = true,
                "--home-switch-mm" => a.home_switch_mm = Some(num(v()?)?),
                "-h" | "--help" => return Err(ArgsError::Help),
                _ => return Err(ArgsError::UnknownOption(k.clone())),
            }
        }
        let units_ok = a.units_per_rpm.is_finite() && a.units_per_rpm > 0.0;
        let ramp_ok = a.ramp_rpm_s.is_finite() && a.ramp_rpm_s >= 0.0;
        if !(units_ok && ramp_ok) {
            return Err(ArgsError::SpindleRange);
        }
        Ok(a)
    }

    /// A drive with these options; in velocity mode it ramps at `ramp_rpm_s`.
    pub fn drive(&self) -> crate::cia402_drive::Cia402Drive {
        let mut d = crate::cia402_drive::Cia402Drive::new(
            self.params,
            self.increments_per_mm,
            self.start_mm,
        );
        d.velocity_ramp_units_s2 = self.ramp_rpm_s * self.units_per_rpm;
        d.home_switch_mm = self.home_switch_mm;
        d
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn commands() {
        assert_eq!(
            parse("heartbeat off 2"),
            Ok(Command::Heartbeat(false, Some(2)))
        );
        assert_eq!(parse("fault 2310"), Ok(Command::Fault(0x2310, None)));
        assert_eq!(parse(" silent on "), Ok(Command::Silent(true, None)));
        assert_eq!(parse("fault xyz"), Err(CommandError::ExpectedHexCode));
        assert_eq!(parse("jump").unwrap_err().code(), "sim_unknown_command");
        assert_eq!(parse("heartbeat maybe"), Err(CommandError::ExpectedOnOff));
        assert_eq!(
            parse("input 10 12 1"),
            Ok(Command::Input {
                node: 10,
                bit: 12,
                on: true
            })
        );
        assert_eq!(parse("input 10 64 1"), Err(CommandError::ExpectedInput));
        assert_eq!(parse("input 10 1 on"), Err(CommandError::ExpectedInput));
        assert_eq!(parse("outputs 10"), Ok(Command::Outputs(10)));
    }

    #[test]
    fn args() {
        let a = SimArgs::parse(
            ["--node", "1", "--node", "2", "--window-mm", "5"]
                .into_iter()
                .map(String::from),
        )
        .unwrap();
        assert_eq!(a.nodes, [1, 2]);
        let io = SimArgs::parse(
            ["--io-module", "10", "--io-module", "11", "--io-groups", "2"]
                .into_iter()
                .map(String::from),
        )
        .unwrap();
        assert_eq!((io.io_modules, io.io_groups), (vec![10, 11], 2));
        assert_eq!(
            SimArgs::parse(["--io-groups", "9"].into_iter().map(String::from))
                .unwrap_err()
                .code(),
            "sim_bad_groups"
        );
        assert_eq!(a.drive().velocity_ramp_units_s2, 2000.0);
        let s = SimArgs::parse(
            ["--spindle", "--units-per-rpm", "10", "--ramp-rpm-s", "500"]
                .into_iter()
                .map(String::from),
        )
        .unwrap();
        assert!(s.spindle);
        assert_eq!(s.drive().velocity_ramp_units_s2, 5000.0);
        assert_eq!(
            SimArgs::parse(["--units-per-rpm", "0"].into_iter().map(String::from)),
            Err(ArgsError::SpindleRange)
        );
        assert_eq!(a.params.following_window_mm, 5.0);
        assert_eq!(
            SimArgs::parse(["--node", "200"].into_iter().map(String::from)),
            Err(ArgsError::NodeIdRange(200))
        );
    }
}
