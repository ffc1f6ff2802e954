//! Compiles `proto/cnc/v1/*.proto` without a system `protoc`: protox parses the files in pure
//! Rust and tonic-prost-build generates the code from the descriptor set. The encoded descriptor
//! set is also written to `OUT_DIR` for gRPC server reflection.
use prost::Message;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let protos = ["proto/cnc/v1/cnc.proto"];
    for p in protos {
        println!("cargo:rerun-if-changed={p}");
    }
    let fds = protox::compile(protos, ["proto"])?;
    let out = std::path::PathBuf::from(std::env::var("OUT_DIR")?);
    std::fs::write(out.join("cnc_descriptor.bin"), fds.encode_to_vec())?;
    // Our codec: undecodable requests (text that is not UTF-8) are INVALID_ARGUMENT with a
    // location, not INTERNAL.
    tonic_prost_build::configure()
        .codec_path("crate::codec::CncCodec")
        .compile_fds(fds)?;
    Ok(())
}
