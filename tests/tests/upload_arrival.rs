//! Issue #49: an upload is validated while its chunks arrive (`runtime::arrival`), through
//! `Programs.Upload` on the daemon's socket: progress of the validation comes before the last
//! chunk is sent, the verdict is the whole program's, an upload abandoned mid-way ends its
//! validation (no thread or temporary file is left behind), uploads beyond those validated
//! as they arrive are validated at their end, and a stream silent for a minute is abandoned.

mod api_common;

use std::time::Duration;

use api_common::*;
use daemon::runtime::config::Role;
use proto::v1 as pb;
use proto::v1::programs_client::ProgramsClient;
use tokio::sync::mpsc;
use tokio_stream::wrappers::ReceiverStream;
use tonic::transport::Channel;

/// `runtime::api::receiving::ARRIVING_AT_ONCE`.
const ARRIVING_AT_ONCE: usize = 2;

/// `n` valid blocks from block `first` on.
fn blocks(first: usize, n: usize) -> String {
    (first..first + n)
        .map(|i| format!("G1 X{}.{} F500\n", i % 100, i % 7))
        .collect()
}

fn chunk(name: &str, data: String) -> pb::ProgramChunk {
    pb::ProgramChunk {
        name: name.into(),
        data: data.into_bytes(),
        select: !name.is_empty(),
        ..Default::default()
    }
}

/// Threads of this process named `name` (the validation's is `cnc-upload`).
fn threads_named(name: &str) -> usize {
    std::fs::read_dir("/proc/self/task")
        .unwrap()
        .filter_map(|t| std::fs::read_to_string(t.ok()?.path().join("comm")).ok())
        .filter(|c| c.trim() == name)
        .count()
}

fn upload_files(d: &Daemon) -> usize {
    std::fs::read_dir(d.ctl.config().storage.programs_path())
        .map(|r| {
            r.filter(|e| {
                e.as_ref()
                    .is_ok_and(|e| e.file_name().to_string_lossy().starts_with(".upload-"))
            })
            .count()
        })
        .unwrap_or(0)
}

/// A streamed upload of `name` whose first chunk of 70,000 blocks is sent, the stream kept
/// open: its sender and its replies.
async fn open_upload(
    g: &mut ProgramsClient<Channel>,
    name: &str,
) -> (
    mpsc::Sender<pb::ProgramChunk>,
    tonic::Streaming<pb::UploadProgress>,
) {
    let (tx, rx) = mpsc::channel(4);
    tx.send(chunk(name, blocks(0, 70_000))).await.unwrap();
    let replies = g
        .upload(ReceiverStream::new(rx))
        .await
        .unwrap()
        .into_inner();
    (tx, replies)
}

/// `UploadBegin` with `data`: the session and the bytes sent.
async fn begin(g: &mut ProgramsClient<Channel>, name: &str, data: String) -> (String, u64) {
    let bytes = data.len() as u64;
    let s = g
        .upload_begin(chunk(name, data))
        .await
        .unwrap()
        .into_inner();
    (s.id, bytes)
}

async fn part(
    g: &mut ProgramsClient<Channel>,
    id: &str,
    offset: u64,
    data: String,
) -> Result<pb::UploadProgress, tonic::Status> {
    let r = pb::UploadPartRequest {
        id: id.into(),
        offset,
        data: data.into_bytes(),
    };
    g.upload_part(r).await.map(tonic::Response::into_inner)
}

/// Waits (at most 30 s) for a progress message with at least `blocks` validated.
async fn validated(replies: &mut tonic::Streaming<pb::UploadProgress>, blocks: u32) -> u64 {
    tokio::time::timeout(Duration::from_secs(30), async {
        loop {
            let p = replies
                .message()
                .await
                .unwrap()
                .expect("the upload ended early");
            assert!(p.done.is_none(), "done before the last chunk");
            if p.blocks_validated >= blocks {
                return p.bytes_stored;
            }
        }
    })
    .await
    .expect("no progress of the validation while the upload is open")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn uploads_are_validated_as_they_arrive_and_an_abandoned_one_ends() {
    let mut cfg = config(Role::Operator);
    cfg.storage.programs_max_bytes = 3 << 20;
    let d = start(cfg).await;
    let mut g = ProgramsClient::new(d.channel().await);

    // 70,000 blocks sent, the stream still open: the validation is past 65,536 of them.
    let (tx, mut replies) = open_upload(&mut g, "arriving.nc").await;
    let first_bytes = blocks(0, 70_000).len() as u64;
    assert_eq!(validated(&mut replies, 65_536).await, first_bytes);
    tx.send(chunk("", blocks(70_000, 10))).await.unwrap();
    drop(tx);
    let done = loop {
        let p = replies.message().await.unwrap().expect("an answer");
        if let Some(done) = p.done {
            break done;
        }
    };
    let program = done.program.unwrap();
    assert_eq!(
        (program.blocks, program.valid, done.selected),
        (70_010, true, true)
    );
    assert_eq!(d.ctl.program().unwrap().block_count, 70_010);

    // Through the sessions' door (the browser's): an upload the library cannot take is
    // abandoned mid-way; its validation, waiting for more, ends and its file goes.
    let (id, _) = begin(&mut g, "abandoned.nc", blocks(0, 70_000)).await;
    wait_until("its validation waits for more", || {
        threads_named("cnc-upload") == 1
    })
    .await;
    assert_eq!(upload_files(&d), 1);
    let e = part(&mut g, &id, first_bytes, "G1 X1\n".repeat(200_000))
        .await
        .unwrap_err();
    assert_eq!(e.code(), tonic::Code::ResourceExhausted, "{e:?}");
    wait_until("the abandoned upload's validation ends", || {
        threads_named("cnc-upload") == 0 && upload_files(&d) == 0
    })
    .await;
    assert_eq!(
        d.ctl.program().unwrap().name,
        "arriving.nc",
        "still selected"
    );

    // More uploads at once than are validated as they arrive: the others at their end.
    let mut open = Vec::new();
    for k in 0..=ARRIVING_AT_ONCE {
        open.push(begin(&mut g, &format!("p{k}.nc"), blocks(0, 1000 + k)).await);
    }
    wait_until("the first ones validate as they arrive", || {
        threads_named("cnc-upload") == ARRIVING_AT_ONCE
    })
    .await;
    for (k, (id, bytes)) in open.iter().enumerate() {
        part(&mut g, id, *bytes, blocks(5000, 10)).await.unwrap();
        let done = g
            .upload_finish(pb::UploadSession { id: id.clone() })
            .await
            .unwrap()
            .into_inner();
        assert_eq!(done.program.unwrap().blocks as usize, 1010 + k);
    }
    assert_eq!(d.ctl.program().unwrap().name, "p2.nc");
    // (A validation thread ends just after it has handed its result over.)
    wait_until("every validation thread ends", || {
        threads_named("cnc-upload") == 0
    })
    .await;
}

/// A streamed upload whose client goes silent is abandoned after a minute without a chunk
/// (`DEADLINE_EXCEEDED`, as an idle upload session is dropped): its validation ends, its
/// temporary file goes and the selection stays. The runtime's clock is paused once the first
/// chunk is in, so the minute passes at once.
#[tokio::test(flavor = "current_thread")]
async fn a_silent_upload_stream_is_abandoned_after_a_minute() {
    let d = start(config(Role::Operator)).await;
    let mut g = ProgramsClient::new(d.channel().await);
    let (tx, mut replies) = open_upload(&mut g, "silent.nc").await;
    validated(&mut replies, 65_536).await;
    tokio::time::pause();
    let silent_from = tokio::time::Instant::now();
    let status = loop {
        match replies.message().await {
            Ok(Some(p)) => assert!(p.done.is_none(), "no verdict on a silent upload"),
            Ok(None) => panic!("the stream ended without an answer"),
            Err(status) => break status,
        }
    };
    assert_eq!(status.code(), tonic::Code::DeadlineExceeded, "{status:?}");
    // (The server's minute began with the chunk, a moment before the clock was paused.)
    assert!(silent_from.elapsed() >= Duration::from_secs(59));
    tokio::time::resume();
    wait_until("its temporary file goes", || upload_files(&d) == 0).await;
    assert!(d.ctl.program().is_none(), "nothing selected");
    drop(tx);
}
