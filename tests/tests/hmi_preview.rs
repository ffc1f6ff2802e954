//! `Preview.GetPreviewOutline` over grpc-web (issue #30): the browser draws a program of any
//! size from the server's outline of the selected program, collected by the pass that
//! validated the selection (no pass of its own), bounded per view, finer for a zoomed extent
//! (a pass of its own, clipped), with the tool-centre path of radius compensation; a setup
//! changed since the selection is outlined by one pass of its own, kept; a running job shows
//! the pass it validated with.

mod api_common;
mod hmi_common;

use api_common::{OPERATOR_TOKEN, config, with_token};
use daemon::runtime::config::Role;
use daemon::runtime::rt::MachineState;
use hmi_common::wait_state;
use proto::v1 as pb;
use proto::v1::offsets_client::OffsetsClient;
use proto::v1::preview_client::PreviewClient;
use tonic::Code;

fn preview(h: &hmi_common::Hmi) -> PreviewClient<hmi_common::Web> {
    let (svc, origin) = hmi_common::web_channel(&h.base);
    PreviewClient::with_origin(svc, origin)
}

/// The whole XY outline of the selected program (or of the running job).
async fn outline(p: &mut PreviewClient<hmi_common::Web>) -> pb::PreviewOutline {
    p.get_preview_outline(whole("xy"))
        .await
        .unwrap()
        .into_inner()
}

fn whole(plane: &str) -> pb::PreviewOutlineRequest {
    pb::PreviewOutlineRequest {
        plane: plane.into(),
        width_px: 1000,
        height_px: 800,
        ..Default::default()
    }
}

fn points(p: &Option<pb::Polylines>) -> usize {
    p.as_ref().map_or(0, |p| p.xy_mm.len() / 2)
}

/// A contour under G41 (tool radius 3 mm), then a continuous (G23) raster of `rows` x 1000
/// short moves.
fn program(rows: u32) -> String {
    let mut t = String::from(
        "N1 G92 D1 R0=3.0\nN2 G17 D1\nN3 G0 X-10 Y-10\nN4 G41 G1 X0 Y0 F3000\n\
         N5 Y80\nN6 X100\nN7 Y0\nN8 X0\nN9 G40 G1 X-10 Y-10\nN10 G23\n",
    );
    for row in 0..rows {
        for col in 0..1000 {
            let x = if row % 2 == 0 { col } else { 999 - col } as f64 * 0.1;
            let y = 5.0 + row as f64 * 0.1 + if col % 7 == 0 { 0.02 } else { 0.0 };
            t += &format!("G1 X{x:.3} Y{y:.3}\n");
        }
    }
    t
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_selected_programs_outline_is_bounded_true_and_refined_on_zoom() {
    let h = hmi_common::start(config(Role::Admin)).await;
    let mut p = preview(&h);
    let e = p.get_preview_outline(whole("xy")).await.unwrap_err();
    assert_eq!(e.code(), Code::FailedPrecondition, "{e:?}");

    let text = program(60);
    h.machine()
        .load_program(with_token(
            pb::LoadProgramRequest {
                name: "cam.nc".into(),
                text,
                dialect: String::new(),
            },
            OPERATOR_TOKEN,
        ))
        .await
        .unwrap();
    let passes = h.ctl.validation_passes();
    let o = outline(&mut p).await;
    assert_eq!(
        h.ctl.validation_passes(),
        passes,
        "read from the selection's pass"
    );
    assert!(!o.own_pass);
    assert_eq!((o.program.as_str(), o.blocks), ("cam.nc", 60_010));
    // The whole program's box: the rapid from X-10 Y-10, the contour, the tool centre.
    assert!(o.min_h_mm <= -10.0 && o.max_h_mm >= 100.0, "{o:?}");
    assert!(o.min_v_mm <= -10.0 && o.max_v_mm >= 80.0);
    // Bounded: a screenful, not 60,000 blocks.
    assert!(
        points(&o.feed) > 100 && points(&o.feed) <= 1 << 16,
        "{}",
        points(&o.feed)
    );
    assert!(points(&o.rapid) >= 2);
    assert!(points(&o.compensated) >= 4, "the tool-centre path is sent");
    assert!(o.smooth_junctions + o.red_junctions >= 60_000);
    assert!(!o.red_xy_mm.is_empty() && !o.smooth_xy_mm.is_empty());
    assert!(o.cell_mm > 0.0 && o.cell_mm < 0.5, "{}", o.cell_mm);

    // A zoom on 2 mm of the raster: finer, from the outline (fine enough for 60,000 blocks).
    let zoom = pb::PreviewOutlineRequest {
        min_h_mm: 40.0,
        min_v_mm: 6.0,
        max_h_mm: 42.0,
        max_v_mm: 8.0,
        ..whole("xy")
    };
    let z = p.get_preview_outline(zoom).await.unwrap().into_inner();
    assert!(z.cell_mm < o.cell_mm / 2.0, "{} {}", z.cell_mm, o.cell_mm);
    let xy = &z.feed.as_ref().unwrap().xy_mm;
    assert!(!xy.is_empty());
    assert!(
        xy.chunks(2).all(|q| q[0] > 30.0 && q[0] < 52.0),
        "clipped to the extent"
    );
    // The same box as the whole program's (to fit it).
    assert_eq!((z.min_h_mm, z.max_v_mm), (o.min_h_mm, o.max_v_mm));

    // Zoomed finer than the outline's grid: a pass of its own, clipped to the extent.
    let passes = h.ctl.validation_passes();
    let deep = pb::PreviewOutlineRequest {
        min_h_mm: 40.0,
        min_v_mm: 6.0,
        max_h_mm: 40.01,
        max_v_mm: 6.01,
        ..whole("xy")
    };
    let d = p.get_preview_outline(deep).await.unwrap().into_inner();
    assert!(
        d.own_pass && d.cell_mm < z.cell_mm,
        "{} {}",
        d.cell_mm,
        z.cell_mm
    );
    assert_eq!(h.ctl.validation_passes(), passes + 1);

    // Other planes, a lathe's ZX too; an unknown plane is refused.
    let xz = p
        .get_preview_outline(whole("zx"))
        .await
        .unwrap()
        .into_inner();
    assert!(points(&xz.feed) > 0);
    let e = p.get_preview_outline(whole("xq")).await.unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument, "{e:?}");
}

/// Largest x of a polyline set (the tool-centre path's right side).
fn max_x(p: &Option<pb::Polylines>) -> f32 {
    let xy = &p.as_ref().unwrap().xy_mm;
    xy.chunks(2).map(|q| q[0]).fold(f32::MIN, f32::max)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_changed_setup_is_outlined_once_and_a_running_job_shows_what_it_runs() {
    let h = hmi_common::start(config(Role::Admin)).await;
    let mut p = preview(&h);
    let (svc, origin) = hmi_common::web_channel(&h.base);
    let mut offsets = OffsetsClient::with_origin(svc, origin);
    let radius = |r: f64| {
        with_token(
            pb::SetOffsetRequest {
                entry: 1,
                radius_mm: Some(r),
                ..Default::default()
            },
            OPERATOR_TOKEN,
        )
    };
    offsets.set_offset(radius(2.0)).await.unwrap();
    // A 40 mm square under G41 with the radius of entry 1, then slow continuous (G23) moves (a
    // run to look at, a smooth junction).
    let text = "N1 G17 D1\nN2 G0 X-10 Y-10\nN3 G41 G1 X0 Y0 F3000\nN4 Y40\nN5 X40\nN6 Y0\n\
                N7 X0\nN8 G40 G1 X-10 Y-10\nN9 G23 G1 Y-30 F200\nN10 Y-60\n";
    h.machine()
        .load_program(with_token(
            pb::LoadProgramRequest {
                name: "square.nc".into(),
                text: text.into(),
                dialect: String::new(),
            },
            OPERATOR_TOKEN,
        ))
        .await
        .unwrap();
    let selected = outline(&mut p).await;
    assert!(!selected.own_pass);
    assert!((max_x(&selected.compensated) - 42.0).abs() < 0.01);

    // The tool table changed since the selection: one pass of its own, kept for the next views.
    offsets.set_offset(radius(5.0)).await.unwrap();
    let passes = h.ctl.validation_passes();
    let changed = outline(&mut p).await;
    assert!(changed.own_pass);
    assert!((max_x(&changed.compensated) - 45.0).abs() < 0.01);
    assert_eq!(h.ctl.validation_passes(), passes + 1);
    let again = outline(&mut p).await;
    assert_eq!(
        h.ctl.validation_passes(),
        passes + 1,
        "the same setup: no pass again"
    );
    assert_eq!(again.compensated, changed.compensated);
    assert!(again.own_pass);

    // Started: the job validates again with the radius in force, and that is what is shown
    // while it runs (no pass of the preview's own, not even for a deep zoom).
    h.machine()
        .start(with_token(pb::StartRequest::default(), OPERATOR_TOKEN))
        .await
        .unwrap();
    wait_state(&h.ctl, MachineState::Running).await;
    let passes = h.ctl.validation_passes();
    let running = outline(&mut p).await;
    assert!(!running.own_pass);
    assert_eq!(running.compensated, changed.compensated, "the job's pass");
    let deep = pb::PreviewOutlineRequest {
        min_h_mm: 0.0,
        min_v_mm: 0.0,
        max_h_mm: 0.01,
        max_v_mm: 0.01,
        ..whole("xy")
    };
    let d = p.get_preview_outline(deep).await.unwrap().into_inner();
    assert!(!d.own_pass);
    assert_eq!(h.ctl.validation_passes(), passes);
    assert_eq!(h.ctl.snapshot().state, MachineState::Running);
    h.machine()
        .stop(with_token(pb::StopRequest::default(), OPERATOR_TOKEN))
        .await
        .unwrap();
    wait_state(&h.ctl, MachineState::Idle).await;

    // Single block: the job's pass ends every block at rest, so every junction is a stop.
    let mut m = h.machine();
    m.set_single_block(with_token(
        pb::SetSingleBlockRequest { enabled: true },
        OPERATOR_TOKEN,
    ))
    .await
    .unwrap();
    m.start(with_token(pb::StartRequest::default(), OPERATOR_TOKEN))
        .await
        .unwrap();
    let single = outline(&mut p).await;
    assert!(changed.smooth_junctions > 0);
    assert_eq!(single.smooth_junctions, 0);
    assert_eq!(
        single.red_junctions,
        changed.smooth_junctions + changed.red_junctions
    );
    m.stop(with_token(pb::StopRequest::default(), OPERATOR_TOKEN))
        .await
        .unwrap();
    wait_state(&h.ctl, MachineState::Idle).await;
}
