//! Generated gRPC/protobuf code of the controller API, package `cnc.v1`.
pub mod cnc {
    pub mod v1 {
        tonic::include_proto!("cnc.v1");
    }
}
pub use cnc::v1;
