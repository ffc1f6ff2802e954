//! Chunked program upload over grpc-web (issue #30): `Programs.UploadBegin`, `UploadPart`,
//! `UploadFinish`, as a browser uploads a CAM-size file without client streaming; the result
//! is what the streaming `Upload` gives (stored, selected, diagnostics with codes).

mod api_common;
mod hmi_common;

use api_common::{ADMIN_TOKEN, OPERATOR_TOKEN, config, diagnostics, with_token};
use daemon::runtime::config::Role;
use proto::v1 as pb;
use proto::v1::programs_client::ProgramsClient;
use tonic::Code;

/// Part size: a browser sends 1 MiB slices, below the 4 MiB message limit.
const PART_BYTES: usize = 1 << 20;

type Programs = ProgramsClient<hmi_common::Web>;

async fn begin(p: &mut Programs, name: &str, select: bool, first: &[u8], total: usize) -> String {
    let chunk = pb::ProgramChunk {
        name: name.into(),
        data: first.to_vec(),
        select,
        total_bytes: total as u64,
        dialect: String::new(),
    };
    p.upload_begin(with_token(chunk, OPERATOR_TOKEN))
        .await
        .unwrap()
        .into_inner()
        .id
}

fn part(id: &str, offset: usize, data: &[u8]) -> tonic::Request<pb::UploadPartRequest> {
    with_token(
        pb::UploadPartRequest {
            id: id.into(),
            offset: offset as u64,
            data: data.to_vec(),
        },
        OPERATOR_TOKEN,
    )
}

fn finish(id: &str) -> tonic::Request<pb::UploadSession> {
    with_token(pb::UploadSession { id: id.into() }, OPERATOR_TOKEN)
}

/// Uploads `text` in [`PART_BYTES`] parts (the first with UploadBegin) and finishes.
async fn upload(
    p: &mut Programs,
    name: &str,
    text: &[u8],
) -> Result<pb::UploadDone, tonic::Status> {
    let first = &text[..text.len().min(PART_BYTES)];
    let id = begin(p, name, true, first, text.len()).await;
    let mut offset = first.len();
    while offset < text.len() {
        let end = (offset + PART_BYTES).min(text.len());
        let r = p.upload_part(part(&id, offset, &text[offset..end])).await?;
        assert_eq!(r.into_inner().bytes_stored, end as u64);
        offset = end;
    }
    p.upload_finish(finish(&id)).await.map(|r| r.into_inner())
}

/// A CAM-like program of `blocks` short moves (about 20 bytes each).
fn cam_program(blocks: u32) -> String {
    let mut text = String::from("N1 G1 X0 Y0 F6000\n");
    for i in 0..blocks {
        let x = (i % 100) as f64 * 0.01;
        text.push_str(&format!("G1 X{x:.2} Y{:.2}\n", (i % 7) as f64 * 0.01));
    }
    text
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_cam_size_program_uploads_in_parts_and_is_stored_and_selected() {
    let h = hmi_common::start(config(Role::Admin)).await;
    let mut p = h.programs();
    let text = cam_program(400_000);
    assert!(text.len() > 5 << 20, "{} bytes", text.len());
    let done = upload(&mut p, "cam.nc", text.as_bytes()).await.unwrap();
    assert!(done.selected);
    let stored = done.program.unwrap();
    assert_eq!(stored.blocks, 400_001);
    assert_eq!(stored.size_bytes, text.len() as u64);
    assert!(stored.valid);
    assert_eq!(h.ctl.program().unwrap().name, "cam.nc");
    let list = p
        .list(pb::LibraryListRequest {})
        .await
        .unwrap()
        .into_inner();
    assert_eq!(list.selected, "cam.nc");
    // Downloaded again over grpc-web (server streaming): the same bytes.
    let mut d = p
        .download(pb::ProgramName {
            name: "cam.nc".into(),
        })
        .await
        .unwrap()
        .into_inner();
    let mut back = Vec::new();
    while let Some(c) = d.message().await.unwrap() {
        back.extend_from_slice(&c.data);
    }
    assert!(back == text.as_bytes(), "the downloaded text differs");
    assert_no_temporary_files(&h);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_bad_program_is_refused_with_coded_diagnostics_and_not_stored() {
    let h = hmi_common::start(config(Role::Admin)).await;
    let mut p = h.programs();
    let text = "N10 G1 X10 F1000\nN20 G2 X20 Y0 I3 J0\nN30 G1 X0 Q\n";
    let e = upload(&mut p, "bad.nc", text.as_bytes()).await.unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument, "{e:?}");
    let d = diagnostics(&e);
    assert!(!d.is_empty(), "{e:?}");
    assert!(d.iter().all(|d| !d.code.is_empty() && d.line > 0), "{d:?}");
    let list = p
        .list(pb::LibraryListRequest {})
        .await
        .unwrap()
        .into_inner();
    assert!(list.programs.iter().all(|e| e.name != "bad.nc"), "{list:?}");
    assert!(h.ctl.program().is_none());
    assert_no_temporary_files(&h);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn parts_out_of_order_and_other_callers_sessions_are_refused() {
    let h = hmi_common::start(config(Role::Admin)).await;
    let mut p = h.programs();
    let id = begin(&mut p, "p.nc", false, b"N10 G1 X1", 20).await;
    let e = p.upload_part(part(&id, 3, b"0 F100\n")).await.unwrap_err();
    assert_eq!(e.code(), Code::FailedPrecondition, "{e:?}");
    assert!(e.message().contains("send the part at 9"), "{e:?}");
    // Another token's caller does not see the session.
    let mut other = pb::UploadPartRequest {
        id: id.clone(),
        offset: 9,
        data: b"0 F100\n".to_vec(),
    };
    let e = p
        .upload_part(with_token(other.clone(), ADMIN_TOKEN))
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::NotFound, "{e:?}");
    other.id = "no-such-session".into();
    let e = p
        .upload_part(with_token(other, OPERATOR_TOKEN))
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::NotFound, "{e:?}");
    // The session survived the refusals.
    p.upload_part(part(&id, 9, b"0 F100\n")).await.unwrap();
    let done = p.upload_finish(finish(&id)).await.unwrap().into_inner();
    assert!(!done.selected);
    assert_eq!(done.program.unwrap().size_bytes, 16);
    // A finished session is gone.
    let e = p.upload_finish(finish(&id)).await.unwrap_err();
    assert_eq!(e.code(), Code::NotFound, "{e:?}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn open_sessions_are_bounded() {
    let h = hmi_common::start(config(Role::Admin)).await;
    let mut p = h.programs();
    let max = daemon::runtime::api::upload_session::MAX_SESSIONS;
    for i in 0..max {
        begin(&mut p, &format!("p{i}.nc"), false, b"", 0).await;
    }
    let chunk = pb::ProgramChunk {
        name: "one-too-many.nc".into(),
        ..Default::default()
    };
    let e = p
        .upload_begin(with_token(chunk, OPERATOR_TOKEN))
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::ResourceExhausted, "{e:?}");
    let e = p
        .upload_begin(with_token(
            pb::ProgramChunk {
                name: String::new(),
                ..Default::default()
            },
            OPERATOR_TOKEN,
        ))
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument, "{e:?}");
}

/// The library holds no temporary upload file.
fn assert_no_temporary_files(h: &hmi_common::Hmi) {
    let dir = h.ctl.config().storage.programs_path();
    let tmp: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| {
            let n = e.unwrap().file_name().to_string_lossy().into_owned();
            n.contains("upload").then_some(n)
        })
        .collect();
    assert!(tmp.is_empty(), "{tmp:?}");
}
