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
    tonic_prost_build::configure().compile_fds(fds)?;
    Ok(())
}
