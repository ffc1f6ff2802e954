//! Generated gRPC/protobuf code of the controller API, package `cnc.v1`, with its codec
//! ([`codec::CncCodec`]).
pub mod codec;
pub mod cnc {
    pub mod v1 {
        tonic::include_proto!("cnc.v1");
    }
}
pub use cnc::v1;

/// Encoded `FileDescriptorSet` of `cnc.v1`, for gRPC server reflection.
pub const FILE_DESCRIPTOR_SET: &[u8] =
    include_bytes!(concat!(env!("OUT_DIR"), "/cnc_descriptor.bin"));
