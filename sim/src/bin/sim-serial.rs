//! `sim-serial --link /tmp/drive.tty --axes 3 [--spindle]`: a simulated drive unit behind the
//! serial protocol on a pseudo-terminal; `--spindle` adds a spindle drive (protocol version 2,
//! ramping at `--ramp-rpm-s` with `--units-per-rpm`). The controller opens `--link`, a symlink to the pty; `unplug`
//! on stdin closes the pty (the controller sees a hang-up), `plug` creates a new one behind
//! the same link. Other fault injection: see `sim::control`.
//!
//! Homing (protocol version 3): `--home-switch AXIS:MM:SIDE` (repeatable) gives axis AXIS
//! (1-based) a home switch at MM (power-on coordinates) pressed on side SIDE (-1: at and
//! below, 1: at and above); `--protocol 3` (or 2, 1) plays an old unit that does not answer
//! newer requests. `--watchdog-ms MS` sets the communication watchdog (default 100).
//!
//! Digital I/O (protocol version 4), by lines on stdin besides `sim::control`'s: `inputs HEX`
//! sets the unit's input word, `input BIT on|off` one bit; `io` prints
//! `io inputs XXXXXXXXXXXXXXXX outputs XXXXXXXXXXXXXXXX safe XXXXXXXXXXXXXXXX fallen yes|no`.

use std::io::{BufRead, Read, Write};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use serialport::{SerialPort, TTYPort};
use sim::control::{self, Command, SimArgs};
use sim::serial_drive::{IoWords, SerialDriveUnit};

/// A pty pair with the link pointing at its slave side. The slave fd stays open here so
/// the master side does not read EIO before the controller opens the link.
struct Line {
    master: TTYPort,
    _slave: TTYPort,
}

fn plug(link: &str) -> Line {
    let (mut master, slave) = TTYPort::pair().unwrap_or_else(|e| fail(&format!("no pty: {e}")));
    master
        .set_timeout(Duration::from_millis(2))
        .unwrap_or_else(|e| fail(&e.to_string()));
    let pts = slave.name().unwrap_or_default();
    let tmp = format!("{link}.new");
    let _ = std::fs::remove_file(&tmp);
    std::os::unix::fs::symlink(&pts, &tmp)
        .and_then(|()| std::fs::rename(&tmp, link))
        .unwrap_or_else(|e| fail(&format!("cannot link {link} to {pts}: {e}")));
    println!("sim-serial plugged {link} -> {pts}");
    let _ = std::io::stdout().flush();
    Line {
        master,
        _slave: slave,
    }
}

/// Why the homing options were refused (each message ends the simulator).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
enum HomingArgsError {
    #[error("{0} needs a value")]
    MissingValue(&'static str),
    #[error("bad --home-switch '{0}': give AXIS:MM:SIDE, e.g. 1:-5:-1")]
    BadHomeSwitch(String),
    #[error("bad --protocol '{0}': 1, 2, 3 or 4")]
    BadProtocol(String),
    #[error("bad --watchdog-ms '{0}'")]
    BadWatchdog(String),
}

impl HomingArgsError {
    /// Stable code (tests match it; the message may improve).
    fn code(&self) -> &'static str {
        match self {
            HomingArgsError::MissingValue(_) => "sim_missing_value",
            HomingArgsError::BadHomeSwitch(_) => "sim_bad_home_switch",
            HomingArgsError::BadProtocol(_) => "sim_bad_protocol",
            HomingArgsError::BadWatchdog(_) => "sim_bad_watchdog",
        }
    }
}

/// A home switch option: (axis index, position mm, side).
fn home_switch(v: &str) -> Result<(usize, f64, f64), HomingArgsError> {
    let bad = || HomingArgsError::BadHomeSwitch(v.to_owned());
    let mut w = v.split(':');
    let (Some(a), Some(mm), Some(side), None) = (w.next(), w.next(), w.next(), w.next()) else {
        return Err(bad());
    };
    let axis: usize = a.parse().map_err(|_| bad())?;
    let mm: f64 = mm.parse().map_err(|_| bad())?;
    let side: f64 = side.parse().map_err(|_| bad())?;
    if axis == 0 || !mm.is_finite() || (side != 1.0 && side != -1.0) {
        return Err(bad());
    }
    Ok((axis - 1, mm, side))
}

/// The homing options of this binary; the rest goes to [`SimArgs::parse`].
struct HomingArgs {
    switches: Vec<(usize, f64, f64)>,
    max_version: u8,
    watchdog_ms: Option<u64>,
    rest: Vec<String>,
}

fn homing_args(args: impl Iterator<Item = String>) -> Result<HomingArgs, HomingArgsError> {
    let mut h = HomingArgs {
        switches: Vec::new(),
        max_version: 4,
        watchdog_ms: None,
        rest: Vec::new(),
    };
    let mut it = args;
    let value = |key: &'static str, it: &mut dyn Iterator<Item = String>| {
        it.next().ok_or(HomingArgsError::MissingValue(key))
    };
    while let Some(k) = it.next() {
        match k.as_str() {
            "--home-switch" => h
                .switches
                .push(home_switch(&value("--home-switch", &mut it)?)?),
            "--protocol" => {
                let v = value("--protocol", &mut it)?;
                h.max_version = v
                    .parse()
                    .ok()
                    .filter(|n| (1..=4).contains(n))
                    .ok_or(HomingArgsError::BadProtocol(v))?;
            }
            "--watchdog-ms" => {
                let v = value("--watchdog-ms", &mut it)?;
                h.watchdog_ms = Some(v.parse().map_err(|_| HomingArgsError::BadWatchdog(v))?);
            }
            _ => h.rest.push(k),
        }
    }
    Ok(h)
}

/// The drive unit the options describe.
fn drive_unit(args: &SimArgs, homing: &HomingArgs) -> SerialDriveUnit {
    let drives = (0..args.axes).map(|_| args.drive()).collect();
    let mut unit = SerialDriveUnit::new(drives);
    unit.max_version = homing.max_version;
    if let Some(ms) = homing.watchdog_ms {
        unit.watchdog_ms = ms;
    }
    for &(axis, at, side) in &homing.switches {
        if axis >= args.axes {
            fail(&format!(
                "--home-switch of axis {}: the unit has {}",
                axis + 1,
                args.axes
            ));
        }
        unit = unit.with_home_switch(axis, at, side);
    }
    if args.spindle {
        unit.spindle = Some(args.drive());
    }
    unit
}

/// A line on stdin of the unit's digital I/O.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum IoLine {
    /// `inputs HEX`: the whole input word.
    Inputs(u64),
    /// `input BIT on|off`.
    Input(u8, bool),
    /// `io`: print the words.
    Show,
}

/// Why an I/O line was refused (the simulator says so and goes on).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
enum IoLineError {
    #[error("inputs needs a hex word, e.g. inputs 1F")]
    BadWord,
    #[error("input needs a bit 0..=63 and on or off, e.g. input 5 on")]
    BadBit,
}

/// The I/O line `line` is, `None` if it is none (a `sim::control` command, maybe).
fn io_line(line: &str) -> Option<Result<IoLine, IoLineError>> {
    let w: Vec<&str> = line.split_whitespace().collect();
    Some(match w.as_slice() {
        ["io"] => Ok(IoLine::Show),
        ["inputs", rest @ ..] => match rest {
            [hex] => u64::from_str_radix(hex.trim_start_matches("0x"), 16)
                .map(IoLine::Inputs)
                .map_err(|_| IoLineError::BadWord),
            _ => Err(IoLineError::BadWord),
        },
        ["input", rest @ ..] => match rest {
            [bit, on @ ("on" | "off")] => bit
                .parse()
                .ok()
                .filter(|b| *b < 64)
                .map(|b| IoLine::Input(b, *on == "on"))
                .ok_or(IoLineError::BadBit),
            _ => Err(IoLineError::BadBit),
        },
        _ => return None,
    })
}

/// A line on stdin: a fault-injection command or an I/O line.
#[derive(Clone, Copy, Debug)]
enum StdinLine {
    Control(Command),
    Io(IoLine),
}

/// Reads stdin on a thread (as `control::stdin_commands`, with the I/O lines besides).
fn stdin_lines() -> mpsc::Receiver<StdinLine> {
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        for line in std::io::stdin().lock().lines() {
            let Ok(line) = line else { return };
            if line.trim().is_empty() {
                continue;
            }
            let parsed = match io_line(&line) {
                Some(io) => io.map(StdinLine::Io).map_err(|e| e.to_string()),
                None => control::parse(&line)
                    .map(StdinLine::Control)
                    .map_err(|e| e.to_string()),
            };
            match parsed {
                Ok(l) if tx.send(l).is_err() => return,
                Ok(_) => {}
                Err(e) => eprintln!("sim-serial: {e}"),
            }
        }
    });
    rx
}

/// Applies one I/O line.
fn apply_io(l: IoLine, io: &IoWords) {
    match l {
        IoLine::Inputs(word) => io.set_inputs(word),
        IoLine::Input(bit, on) => io.set_input(bit, on),
        IoLine::Show => {
            println!(
                "io inputs {:016X} outputs {:016X} safe {:016X} fallen {}",
                io.inputs(),
                io.outputs(),
                io.safe_outputs(),
                if io.is_fallen() { "yes" } else { "no" }
            );
            let _ = std::io::stdout().flush();
        }
    }
}

/// Applies one stdin command; `false` on `quit`.
fn apply(c: Command, unit: &mut SerialDriveUnit, line: &mut Option<Line>, link: &str) -> bool {
    eprintln!("sim-serial: {c:?}");
    match c {
        Command::Silent(on, _) => unit.inject.silent = on,
        Command::Corrupt(on, _) => unit.inject.corrupt = on,
        Command::Fault(code, which) => {
            // The spindle is the drive after the axes (`fault CODE <axes + 1>`).
            let all = unit.drives.iter_mut().chain(unit.spindle.as_mut());
            for (i, d) in all.enumerate() {
                if which.is_none_or(|w| usize::from(w) == i + 1) {
                    d.fault(code);
                }
            }
        }
        Command::Unplug => {
            *line = None;
            let _ = std::fs::remove_file(link);
            println!("sim-serial unplugged");
            let _ = std::io::stdout().flush();
        }
        Command::Plug if line.is_none() => {
            unit.reconnect();
            *line = Some(plug(link));
        }
        Command::Quit => return false,
        _ => {}
    }
    true
}

fn main() {
    let homing = homing_args(std::env::args().skip(1))
        .unwrap_or_else(|e| fail(&format!("{e} [{}]", e.code())));
    let args = match SimArgs::parse(homing.rest.iter().cloned()) {
        Ok(a) if !a.link.is_empty() => a,
        Ok(_) => fail("give --link PATH"),
        Err(e) => fail(&e.to_string()),
    };
    let mut unit = drive_unit(&args, &homing);
    let mut line = Some(plug(&args.link));
    let commands = stdin_lines();
    let start = Instant::now();
    let mut buf = [0u8; 512];
    let mut out = Vec::new();
    loop {
        let now_ms = start.elapsed().as_millis() as u64;
        while let Ok(l) = commands.try_recv() {
            match l {
                StdinLine::Io(l) => apply_io(l, &unit.io),
                StdinLine::Control(c) => {
                    if !apply(c, &mut unit, &mut line, &args.link) {
                        return;
                    }
                }
            }
        }
        let Some(l) = line.as_mut() else {
            std::thread::sleep(Duration::from_millis(2));
            unit.poll(now_ms);
            continue;
        };
        match l.master.read(&mut buf) {
            Ok(n) => unit.on_bytes(&buf[..n], now_ms, &mut out),
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
            Err(e) => {
                // EIO while nobody has the line open (between controller sessions).
                eprintln!("sim-serial: read: {e}");
                std::thread::sleep(Duration::from_millis(10));
            }
        }
        if !out.is_empty() {
            if let Err(e) = l.master.write_all(&out) {
                eprintln!("sim-serial: write: {e}");
            }
            out.clear();
        }
        unit.poll(now_ms);
    }
}

fn fail(msg: &str) -> ! {
    eprintln!("sim-serial: {msg}");
    std::process::exit(2)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(args: &[&str]) -> Result<HomingArgs, HomingArgsError> {
        homing_args(args.iter().map(|a| a.to_string()))
    }

    #[test]
    fn homing_options_parse_and_bad_ones_are_refused_by_code() {
        let h = parse(&["--home-switch", "2:-5:-1", "--protocol", "2", "--axes", "3"]).unwrap();
        assert_eq!(h.switches, vec![(1, -5.0, -1.0)]);
        assert_eq!((h.max_version, h.watchdog_ms), (2, None));
        assert_eq!(h.rest, vec!["--axes", "3"]);
        let code = |args: &[&str]| parse(args).err().map(|e| e.code());
        assert_eq!(code(&["--home-switch"]), Some("sim_missing_value"));
        assert_eq!(
            code(&["--home-switch", "0:1:1"]),
            Some("sim_bad_home_switch")
        );
        assert_eq!(
            code(&["--home-switch", "1:1:0"]),
            Some("sim_bad_home_switch")
        );
        assert_eq!(code(&["--protocol", "5"]), Some("sim_bad_protocol"));
        assert_eq!(code(&["--protocol", "4"]), None);
        assert_eq!(code(&["--watchdog-ms", "x"]), Some("sim_bad_watchdog"));
        assert_eq!(code(&["--watchdog-ms", "50"]), None);
    }

    #[test]
    fn io_lines_parse_and_others_are_left_to_control() {
        assert_eq!(io_line("inputs 1F"), Some(Ok(IoLine::Inputs(0x1F))));
        assert_eq!(io_line("input 63 on"), Some(Ok(IoLine::Input(63, true))));
        assert_eq!(io_line("io"), Some(Ok(IoLine::Show)));
        assert_eq!(io_line("input 64 on"), Some(Err(IoLineError::BadBit)));
        assert_eq!(io_line("inputs zz"), Some(Err(IoLineError::BadWord)));
        assert_eq!(io_line("silent on"), None);
    }
}
