//! `sim-serial --link /tmp/drive.tty --axes 3 [--spindle]`: a simulated drive unit behind the
//! serial protocol on a pseudo-terminal; `--spindle` adds a spindle drive (protocol version 2,
//! ramping at `--ramp-rpm-s` with `--units-per-rpm`). The controller opens `--link`, a symlink to the pty; `unplug`
//! on stdin closes the pty (the controller sees a hang-up), `plug` creates a new one behind
//! the same link. Other fault injection: see `sim::control`.
//!
//! Homing (protocol version 3): `--home-switch AXIS:MM:SIDE` (repeatable) gives axis AXIS
//! (1-based) a home switch at MM (power-on coordinates) pressed on side SIDE (-1: at and
//! below, 1: at and above); `--protocol 2` (or 1) plays an old unit that does not answer
//! version 3 requests. `--watchdog-ms MS` sets the communication watchdog (default 100).

use std::io::{Read, Write};
use std::time::{Duration, Instant};

use serialport::{SerialPort, TTYPort};
use sim::control::{self, Command, SimArgs};
use sim::serial_drive::SerialDriveUnit;

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

/// A home switch option: (axis index, position mm, side).
fn home_switch(v: &str) -> Result<(usize, f64, f64), String> {
    let bad = || format!("bad --home-switch '{v}': give AXIS:MM:SIDE, e.g. 1:-5:-1");
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

fn homing_args(args: impl Iterator<Item = String>) -> Result<HomingArgs, String> {
    let mut h = HomingArgs {
        switches: Vec::new(),
        max_version: 3,
        watchdog_ms: None,
        rest: Vec::new(),
    };
    let mut it = args;
    while let Some(k) = it.next() {
        match k.as_str() {
            "--home-switch" => h.switches.push(home_switch(
                &it.next().ok_or("--home-switch needs a value")?,
            )?),
            "--protocol" => {
                let v = it.next().ok_or("--protocol needs a value")?;
                h.max_version = v
                    .parse()
                    .ok()
                    .filter(|n| (1..=3).contains(n))
                    .ok_or(format!("bad --protocol '{v}': 1, 2 or 3"))?;
            }
            "--watchdog-ms" => {
                let v = it.next().ok_or("--watchdog-ms needs a value")?;
                h.watchdog_ms = Some(v.parse().map_err(|_| format!("bad --watchdog-ms '{v}'"))?);
            }
            _ => h.rest.push(k),
        }
    }
    Ok(h)
}

fn main() {
    let homing = homing_args(std::env::args().skip(1)).unwrap_or_else(|e| fail(&e));
    let args = match SimArgs::parse(homing.rest.into_iter()) {
        Ok(a) if !a.link.is_empty() => a,
        Ok(_) => fail("give --link PATH"),
        Err(e) => fail(&e.to_string()),
    };
    let drives = (0..args.axes).map(|_| args.drive()).collect();
    let mut unit = SerialDriveUnit::new(drives);
    unit.max_version = homing.max_version;
    if let Some(ms) = homing.watchdog_ms {
        unit.watchdog_ms = ms;
    }
    for (axis, at, side) in homing.switches {
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
    let mut line = Some(plug(&args.link));
    let commands = control::stdin_commands();
    let start = Instant::now();
    let mut buf = [0u8; 512];
    let mut out = Vec::new();
    loop {
        let now_ms = start.elapsed().as_millis() as u64;
        while let Ok(c) = commands.try_recv() {
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
                    line = None;
                    let _ = std::fs::remove_file(&args.link);
                    println!("sim-serial unplugged");
                    let _ = std::io::stdout().flush();
                }
                Command::Plug if line.is_none() => {
                    unit.reconnect();
                    line = Some(plug(&args.link));
                }
                Command::Quit => return,
                _ => {}
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
