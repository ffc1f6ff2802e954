//! Every command of docs/operator.md and the lathe example of docs/lathe.md, taken from the
//! markdown and run as written (issue #31: "every documented command works as written"):
//! `cncctl` without `--addr`, finding its daemon the way a person's shell would.

mod operator_support;

use std::path::Path;
use std::process::{Child, Command, Stdio};

use operator_support::*;

const REPO: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/..");

/// The commands of a markdown text: the lines of its ```sh blocks and its inline `cncctl ...`
/// spans, in order, each once.
fn commands(md: &str) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    let mut in_sh = false;
    let mut in_other = false;
    for line in md.lines() {
        let t = line.trim_start();
        if t.starts_with("```") {
            if in_sh || in_other {
                (in_sh, in_other) = (false, false);
            } else if t == "```sh" {
                in_sh = true;
            } else {
                in_other = true;
            }
            continue;
        }
        if in_sh {
            if !t.is_empty() {
                out.push(t.to_string());
            }
            continue;
        }
        if in_other {
            continue;
        }
        for (i, span) in line.split('`').enumerate() {
            if i % 2 == 1 && (span == "cncctl" || span.starts_with("cncctl ")) {
                out.push(span.to_string());
            }
        }
    }
    let mut seen = Vec::new();
    for c in out {
        if !seen.contains(&c) {
            seen.push(c);
        }
    }
    seen
}

/// What a documented command does on the simulated mill.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Expect {
    Ok,
    /// Refused as the docs say (FAILED_PRECONDITION: nothing to resume, no fault...).
    Refused,
    /// Either (depends on the machine's state; must answer, not hang or panic).
    Answers,
    /// Runs until interrupted: started, seen working, then ended with a signal.
    Follows,
    /// Not a command: the tool's name, a command named in prose, a placeholder (FILE, NAME).
    Mention,
    /// Runs against the lathe example (see the lathe part of the test).
    Lathe,
}

fn expect(cmd: &str) -> Expect {
    use Expect::*;
    match cmd {
        "cncctl"
        | "cncctl run"
        | "cncctl mdi"
        | "cncctl override"
        | "cncctl offset-set"
        | "cncctl constants set"
        | "cncctl offsets-replace"
        | "cncctl offsets-replace FILE --revision REV"
        | "cncctl trajectory --from-block N"
        | "cncctl start --from-block N" => Mention,
        c if c.contains("FILE") || c.contains("NAME") => Mention,
        "cncctl home"
        | "cncctl home Z"
        | "cncctl home XY"
        | "cncctl start"
        | "cncctl trajectory --from-block 160"
        | "cncctl start --from-block 160 --yes" => Answers,
        "cncctl reset" | "cncctl resume" => Refused,
        "cncctl jog X+ --speed 1000" | "cncctl status --watch" => Follows,
        "cncctl --config programs/lathe/cncd-lathe.toml status" => Lathe,
        "cncctl status"
        | "cncctl jog X --step 1"
        | "cncctl run part.nc"
        | "cncctl stop"
        | "cncctl jog X --step 0.1"
        | "cncctl jog X- --step 0.1"
        | "cncctl status --json"
        | "cncctl optional-stop on"
        | "cncctl alarms"
        | "cncctl offsets-file"
        | "cncctl offsets"
        | "cncctl constants get R39"
        | "cncctl offset-set 3 --radius 2"
        | "cncctl touch-off 1 X 0"
        | "cncctl constants set R52=600"
        | "cncctl --json offsets-file"
        | "cncctl programs"
        | "cncctl --json status --watch | head -1"
        | "cncctl constants get R384"
        | "cncctl load programs/sample.nc"
        | "cncctl block-delete on"
        | "cncctl block-delete off"
        | "cncctl single-block on"
        | "cncctl single-block off"
        | "cncctl validate programs/sample.nc"
        | "cncctl work-offset-set G55 X10 Y-2.5"
        | "cncctl work-offsets" => Ok,
        other => {
            panic!("docs/operator.md documents `{other}`: add it to tests/tests/operator_docs.rs")
        }
    }
}

/// `sh -c LINE` in `cwd`, the built cncd and cncctl first on the PATH, the runtime directory
/// of this test (so only daemons of this test are published).
fn shell(cwd: &Path, line: &str) -> Command {
    let bin_dir = bin("cncctl").parent().unwrap().to_owned();
    bin("cncd");
    let path = format!(
        "{}:{}",
        bin_dir.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let mut c = Command::new("sh");
    c.args(["-c", line])
        .current_dir(cwd)
        .env("PATH", path)
        .env("CNCD_RUNTIME_DIR", cwd.join("run"))
        .env_remove("CNCCTL_ADDR")
        .stdin(Stdio::null());
    c
}

fn run(cwd: &Path, line: &str) -> (bool, String) {
    let out = shell(cwd, line).output().unwrap();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(!text.contains("panicked"), "`{line}`: {text}");
    (out.status.success(), text)
}

/// Starts `line` in the background; ends it with SIGINT (Ctrl-C) once `working` holds.
fn follow(cwd: &Path, line: &str, working: impl FnMut() -> bool) {
    let mut cmd = shell(cwd, &format!("exec {line}"));
    // Ctrl-C as on a terminal: a test run started in the background (`cmd &` in a
    // non-interactive shell) inherits SIGINT ignored, and the command would never end.
    // SAFETY: signal(2) in the child between fork and exec, async-signal-safe.
    unsafe {
        std::os::unix::process::CommandExt::pre_exec(&mut cmd, || {
            libc::signal(libc::SIGINT, libc::SIG_DFL);
            Ok(())
        });
    }
    let mut child: Child = cmd.stdout(Stdio::null()).spawn().unwrap();
    wait_for(line, working);
    // SAFETY: plain syscall on our own child's pid (not yet reaped).
    unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGINT) };
    let _ = child.wait();
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        let target = to.join(e.file_name());
        if e.file_type().unwrap().is_dir() {
            copy_dir(&e.path(), &target);
        } else {
            std::fs::copy(e.path(), target).unwrap();
        }
    }
}

#[test]
fn the_documented_commands_run_as_written() {
    let md = std::fs::read_to_string(format!("{REPO}/docs/operator.md")).unwrap();
    let cwd = temp_dir("docs_mill");
    std::fs::write(cwd.join("part.nc"), "N10 G1 X5 Y5 F3000\nN20 G1 X0 Y0\n").unwrap();
    copy_dir(&Path::new(REPO).join("programs"), &cwd.join("programs"));
    let d = Cncd::start(&cwd, MILL_TOML);
    for cmd in commands(&md) {
        match expect(&cmd) {
            Expect::Mention | Expect::Lathe => {}
            Expect::Ok => {
                let (ok, out) = run(&cwd, &cmd);
                assert!(ok, "`{cmd}` failed: {out}\n{}", d.log());
                d.wait_idle();
            }
            Expect::Refused => {
                let (ok, out) = run(&cwd, &cmd);
                assert!(!ok && out.contains("FailedPrecondition"), "`{cmd}`: {out}");
            }
            Expect::Answers => {
                run(&cwd, &cmd);
                d.wait_idle();
            }
            Expect::Follows => {
                let start = run(&cwd, "cncctl --json status").1;
                follow(&cwd, &cmd, || {
                    let now = run(&cwd, "cncctl --json status").1;
                    now.contains("\"state\":\"jog\"") || (cmd.contains("watch") && now != start)
                });
                d.wait_idle();
            }
        }
    }
    drop(d);

    // docs/lathe.md, "Running the example": the block as written, from a copy of the
    // repository's programs (cncd keeps its data where it starts).
    let lathe = std::fs::read_to_string(format!("{REPO}/docs/lathe.md")).unwrap();
    let block: Vec<String> = commands(&lathe)
        .into_iter()
        .skip_while(|c| !c.starts_with("mkdir -p lathe-data"))
        .take_while(|c| c.starts_with("mkdir") || c.starts_with("cncd") || c.starts_with("cncctl"))
        .collect();
    assert!(
        block.iter().any(|c| c.starts_with("cncctl run")),
        "{block:?}"
    );
    if std::net::TcpListener::bind("127.0.0.1:50051").is_err() {
        println!(
            "SKIPPED the lathe part: 127.0.0.1:50051 (the example's api.listen) is taken here"
        );
        return;
    }
    let cwd = temp_dir("docs_lathe");
    copy_dir(&Path::new(REPO).join("programs"), &cwd.join("programs"));
    let mut daemon: Option<Child> = None;
    for cmd in &block {
        if let Some(bg) = cmd.strip_suffix('&') {
            let log = std::fs::File::create(cwd.join("cncd.log")).unwrap();
            daemon = Some(
                shell(&cwd, &format!("exec {}", bg.trim()))
                    .stdout(log.try_clone().unwrap())
                    .stderr(log)
                    .spawn()
                    .unwrap(),
            );
            wait_for("the lathe cncd published and idle", || {
                run(&cwd, "cncctl --json status")
                    .1
                    .contains("\"state\":\"idle\"")
            });
            continue;
        }
        let (ok, out) = run(&cwd, cmd);
        assert!(ok, "`{cmd}` failed: {out}");
        if cmd.starts_with("cncctl run") {
            assert!(out.contains("program finished"), "{out}");
        }
    }
    for cmd in commands(&md).iter().filter(|c| expect(c) == Expect::Lathe) {
        let (ok, out) = run(&cwd, cmd);
        assert!(ok && out.contains("XØ"), "`{cmd}`: {out}");
    }
    if let Some(mut c) = daemon {
        let _ = c.kill();
        let _ = c.wait();
    }
}
