//! Issue #18 through the API: ValidateProgram runs the whole pipeline (the gouge check
//! included) and returns the R325 refined E per block; GetRefinedProgram gives the program
//! text with E written the way the manual shows (SPEC §4.6).

mod api_common;

use api_common::*;
use daemon::runtime::config::Role;
use proto::v1 as pb;
use proto::v1::machine_client::MachineClient;
use tonic::Code;

/// An arc whose J is 6.992 µm too large (the manual's example E-10006.992 corrects it).
const PROGRAM: &str = "N10 G1 X20 Y10 F500\nN20 G3 X20 Y30 I-10 J10.006992 ; fillet\nN30 G1 X0\n";

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn refinements_are_returned_and_written_as_e() {
    let d = start(config(Role::Admin)).await;
    let mut c = MachineClient::new(d.channel().await);
    // Without R325 the arc misses its circle (R55 = 0.5 µm here).
    d.ctl.set_constants(&[(55, 0.0005)]).unwrap();
    let v = validate(&mut c, PROGRAM).await;
    assert!(!v.valid);
    assert!(v.refinements.is_empty());
    // 8.R325 = 1, limit 10 µm.
    d.ctl.set_constants(&[(325, 10000.010)]).unwrap();
    let v = validate(&mut c, PROGRAM).await;
    assert!(v.valid, "{:?}", v.diagnostics);
    assert_eq!(v.refinements.len(), 1, "{:?}", v.refinements);
    let r = &v.refinements[0];
    assert_eq!((r.block, r.line, r.coordinate.as_str()), (Some(20), 2, "J"));
    assert!((r.delta_mm + 0.006992).abs() < 1e-9, "{}", r.delta_mm);
    assert_eq!(r.e_word, "E-10006.992");
    assert!(
        v.diagnostics
            .iter()
            .any(|d| d.block == Some(20) && d.code == "arc_refined")
    );

    let l = c
        .get_refined_program(pb::RefinedProgramRequest {
            text: PROGRAM.into(),
            dialect: String::new(),
        })
        .await
        .unwrap()
        .into_inner();
    assert_eq!(
        l.text,
        "N10 G1 X20 Y10 F500\nN20 G3 X20 Y30 I-10 J10.006992 E-10006.992 ; fillet\nN30 G1 X0\n"
    );
    assert_eq!(l.refinements, v.refinements);

    // The listing needs no refinement: with R325 off it loads, and its preview path is the
    // refined original's.
    let compile =
        |text: &str| kernel::program::compile(text, d.ctl.machine_setup().unwrap().program());
    let refined_path = compile(PROGRAM).blocks;
    d.ctl.set_constants(&[(325, 0.0)]).unwrap();
    let listed = compile(&l.text);
    assert!(!listed.has_errors(), "{:?}", listed.diagnostics);
    assert_eq!(format!("{refined_path:?}"), format!("{:?}", listed.blocks));

    // Empty text: the selected program; none selected yet.
    let e = c
        .get_refined_program(pb::RefinedProgramRequest {
            text: String::new(),
            dialect: String::new(),
        })
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::FailedPrecondition);
    d.ctl.load_program("listed.nc", &l.text).unwrap();
    let sel = c
        .get_refined_program(pb::RefinedProgramRequest {
            text: String::new(),
            dialect: String::new(),
        })
        .await
        .unwrap()
        .into_inner();
    assert_eq!(sel.text, l.text);
    assert!(sel.refinements.is_empty());
    d.ctl.shutdown();
}

/// A block 1 mm long between two inside corners, tool radius 5: its equidistant loops
/// backwards 4 mm into N40.
const LOOP: &str = "N10 G92 D1 R0=5.0\nN20 G17 D1\nN25 G0 X-10 Y-10\nN30 G41 G1 X0 Y0 F500\n\
N40 G1 X20\nN50 G1 Y1\nN60 G1 X0 Y21\nN70 G40 G1 X-10 Y31\n";

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn validate_program_reports_gouges() {
    let d = start(config(Role::Admin)).await;
    let mut c = MachineClient::new(d.channel().await);
    let v = validate(&mut c, LOOP).await;
    assert!(v.valid, "{:?}", v.diagnostics);
    assert_eq!(v.blocks, 8);
    assert!(
        v.diagnostics.iter().any(|g| g.block == Some(50)
            && g.severity == pb::Severity::Warning as i32
            && g.code == "gouge"
            // The warning names the other block of the pair (docs/compensation.md).
            && g.message.contains("N40")),
        "{:?}",
        v.diagnostics
    );
    d.ctl.set_constants(&[(765, 100.0)]).unwrap(); // 6.R765 = 1: refuse
    let v = validate(&mut c, LOOP).await;
    assert!(!v.valid);
    d.ctl.shutdown();
}
