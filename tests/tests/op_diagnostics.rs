//! Issue #31, diagnostics at any size: a program with 100 000 errors through every door (the
//! gRPC API and `cncctl`) answers the first diagnostics with code, line, column and block and
//! the totals by severity, never a transport error; `validate` of a file over 4 MiB works.

mod api_common;
mod vcan_support;

use std::process::Command;
use std::time::Duration;

use api_common::*;
use daemon::runtime::config::Role;
use proto::v1 as pb;
use proto::v1::machine_client::MachineClient;
use proto::v1::programs_client::ProgramsClient;
use tonic::Code;

const ERRORS: usize = 100_000;

/// The first N diagnostics a reply lists (docs/api.md "Diagnostics at any size").
const LISTED: usize = 200;

/// `ERRORS` lines with a parenthesis (not a comment in this dialect: `unexpected_character`),
/// each line padded with a remark to `line_bytes`.
fn many_errors(line_bytes: usize) -> String {
    let mut text = String::with_capacity(ERRORS * line_bytes);
    for i in 0..ERRORS {
        let head = format!("N{} G1 X{} F500 (c)", i + 1, i % 100);
        let pad = line_bytes.saturating_sub(head.len() + 3);
        text.push_str(&head);
        text.push_str(" ;");
        text.push_str(&"r".repeat(pad));
        text.push('\n');
    }
    text
}

fn check_listed(items: &[pb::Diagnostic], at_most: usize) {
    assert!(
        !items.is_empty() && items.len() <= at_most + 1,
        "{}",
        items.len()
    );
    let first = &items[0];
    assert_eq!(first.code, "unexpected_character", "{first:?}");
    assert_eq!((first.line, first.block), (1, Some(1)), "{first:?}");
    assert!(first.column > 0, "{first:?}");
    // In source order, each located.
    for (k, d) in items.iter().filter(|d| d.line > 0).enumerate() {
        assert_eq!(d.line as usize, k + 1, "{d:?}");
    }
}

fn check_totals(t: Option<pb::DiagnosticCounts>) {
    let t = t.expect("totals");
    assert_eq!(t.errors, ERRORS as u64, "{t:?}");
}

fn check_refusal(e: tonic::Status) {
    use prost::Message;
    assert_eq!(e.code(), Code::InvalidArgument, "{e:?}");
    assert!(e.message().contains("100000 error(s)"), "{}", e.message());
    let d = pb::Diagnostics::decode(e.details()).unwrap();
    check_listed(&d.items, LISTED);
    check_totals(d.totals);
}

fn chunks(name: &str, text: &str) -> Vec<pb::ProgramChunk> {
    text.as_bytes()
        .chunks(1 << 20)
        .enumerate()
        .map(|(i, c)| pb::ProgramChunk {
            name: if i == 0 { name.into() } else { String::new() },
            data: c.to_vec(),
            ..Default::default()
        })
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_hundred_thousand_errors_through_every_api_door() {
    let d = start(config(Role::Admin)).await;
    let mut m = MachineClient::new(d.channel().await);
    let mut g = ProgramsClient::new(d.channel().await);
    // Below the 4 MiB message limit: the unary doors.
    let small = many_errors(12);
    assert!(small.len() < 4 << 20);
    let r = validate(&mut m, &small).await;
    assert!(!r.valid);
    check_listed(&r.diagnostics, LISTED);
    assert_eq!(r.diagnostics.last().unwrap().code, "messages_not_listed");
    check_totals(r.totals);
    for e in [
        m.load_program(named_program("a.nc", &small))
            .await
            .unwrap_err(),
        m.upload_program(named_program("b.nc", &small))
            .await
            .unwrap_err(),
    ] {
        check_refusal(e);
    }
    // Over 4 MiB: the streaming doors.
    let big = many_errors(48);
    assert!(big.len() > 4 << 20, "{}", big.len());
    let r = g
        .validate(tokio_stream::iter(chunks("big.nc", &big)))
        .await
        .unwrap()
        .into_inner();
    assert!(!r.valid);
    check_listed(&r.diagnostics, LISTED);
    check_totals(r.totals);
    let mut s = g
        .upload(tokio_stream::iter(chunks("big.nc", &big)))
        .await
        .unwrap()
        .into_inner();
    let e = loop {
        match s.message().await {
            Ok(Some(_progress)) => continue,
            Ok(None) => panic!("the upload of a program with errors ended without a refusal"),
            Err(e) => break e,
        }
    };
    check_refusal(e);
    // Nothing was stored or selected; a good program still loads and starts (the start door).
    let l = list_programs(&mut m).await;
    assert!(l.programs.is_empty() && l.selected.is_empty(), "{l:?}");
    let job = load_and_start(&mut m, "ok.nc", "G1 X1 F500\n").await;
    assert!(job > 0);
}

/// Runs `cncctl --addr ADDR args..` (60 s hang bound).
async fn cncctl(addr: &str, args: &[&str]) -> (bool, String) {
    let mut all: Vec<String> = vec!["--addr".into(), addr.into()];
    all.extend(args.iter().map(|s| s.to_string()));
    tokio::task::spawn_blocking(move || {
        let mut cmd = Command::new(vcan_support::bin("cncctl"));
        cmd.args(&all).env_remove("CNCCTL_ADDR");
        vcan_support::run_with_timeout(&mut cmd, Duration::from_secs(120))
    })
    .await
    .unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_hundred_thousand_errors_through_cncctl() {
    let d = start(config(Role::Admin)).await;
    let file = d.ctl.config().storage.dir.join("many.nc");
    std::fs::write(&file, many_errors(48)).unwrap();
    let f = file.to_str().unwrap();
    // validate (over 4 MiB): the first 200 and the totals.
    let (ok, out) = cncctl(&d.socket(), &["validate", f]).await;
    assert!(!ok, "{out}");
    assert!(
        !out.contains("h2 protocol") && !out.contains("ResourceExhausted"),
        "{out}"
    );
    assert_eq!(
        out.matches("[unexpected_character]").count(),
        LISTED,
        "{out}"
    );
    assert!(
        out.contains("error [unexpected_character]: line 1:"),
        "{out}"
    );
    assert!(out.contains("totals: 100000 errors"), "{out}");
    // --json: the same, as one value.
    let (ok, out) = cncctl(&d.socket(), &["--json", "validate", f]).await;
    assert!(!ok);
    assert!(out.contains(r#""totals":{"errors":100000"#), "{out}");
    assert!(out.contains(r#""code":"unexpected_character""#), "{out}");
    // upload, load, run: refused with the first diagnostics and the totals.
    for cmd in ["upload", "load", "run"] {
        let (ok, out) = cncctl(&d.socket(), &[cmd, f]).await;
        assert!(!ok, "{cmd}: {out}");
        assert!(out.contains("InvalidArgument: rejected"), "{cmd}: {out}");
        assert!(
            out.contains("error [unexpected_character]: line 1:"),
            "{cmd}: {out}"
        );
        assert!(out.contains("totals: 100000 errors"), "{cmd}: {out}");
        assert!(!out.contains("h2 protocol"), "{cmd}: {out}");
    }
}
