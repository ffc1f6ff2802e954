//! `sim-serial --link /tmp/drive.tty --axes 3 [--spindle]`: a simulated drive unit behind the
//! serial protocol on a pseudo-terminal; `--spindle` adds a spindle drive (protocol version 2,
//! ramping at `--ramp-rpm-s` with `--units-per-rpm`). The controller opens `--link`, a symlink to the pty; `unplug`
//! on stdin closes the pty (the controller sees a hang-up), `plug` creates a new one behind
//! the same link. Other fault injection: see `sim::control`.

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

fn main() {
    let args = match SimArgs::parse(std::env::args().skip(1)) {
        Ok(a) if !a.link.is_empty() => a,
        Ok(_) => fail("give --link PATH"),
        Err(e) => fail(&e.to_string()),
    };
    let drives = (0..args.axes).map(|_| args.drive()).collect();
    let mut unit = SerialDriveUnit::new(drives);
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
