//! Compiles `proto/cnc/v1/*.proto` without a system `protoc`: protox parses the files in pure
//! Rust and tonic-prost-build generates the code from the descriptor set.
fn main() -> Result<(), Box<dyn std::error::Error>> {
    let protos = ["proto/cnc/v1/cnc.proto"];
    for p in protos {
        println!("cargo:rerun-if-changed={p}");
    }
    let fds = protox::compile(protos, ["proto"])?;
    tonic_prost_build::configure().compile_fds(fds)?;
    Ok(())
}
