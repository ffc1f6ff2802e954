//! A start-up seam of `cncd` (issue #50): the Unix socket exists before any TCP listener
//! answers, so a `cncctl` typed the moment the daemon's port answers finds the socket (with
//! the operator's rights) rather than falling back to loopback TCP (observer).

use std::net::TcpStream;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

#[test]
fn the_unix_socket_exists_before_the_tcp_port_answers() {
    let dir = std::env::temp_dir().join(format!("cnc-startup-order-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let sock = dir.join("cncd.sock");
    let cfg = format!(
        "[api]\nlisten = '127.0.0.1:{port}'\nunix_socket = '{}'\n\n[rt]\nlock_memory = false\n\n\
         [storage]\ndir = '{}'\n",
        sock.display(),
        dir.join("data").display()
    );
    std::fs::write(dir.join("cncd.toml"), cfg).unwrap();
    let mut cncd = Command::new(tests::workspace_bin("cncd"))
        .arg("--config")
        .arg(dir.join("cncd.toml"))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let end = Instant::now() + Duration::from_secs(60);
    let answered = loop {
        if TcpStream::connect(("127.0.0.1", port)).is_ok() {
            break true;
        }
        if Instant::now() > end {
            break false;
        }
        std::thread::sleep(Duration::from_millis(1));
    };
    let socket_there = sock.exists();
    let _ = cncd.kill();
    let _ = cncd.wait();
    let _ = std::fs::remove_dir_all(&dir);
    assert!(answered, "cncd's TCP port never answered");
    assert!(
        socket_there,
        "the TCP port answered before the Unix socket existed"
    );
}
