//! relief-proto: the `relief.v1` protobuf types and gRPC stubs.
//!
//! These types live at the gRPC edge only: the daemon converts them to its
//! own types in one place. This crate depends on nothing of relief's.

#[allow(clippy::pedantic, clippy::all, missing_docs)]
pub mod v1 {
    tonic::include_proto!("relief.v1");
    include!(concat!(env!("OUT_DIR"), "/relief.v1.serde.rs"));
}

/// The encoded `FileDescriptorSet` of relief.v1, for gRPC reflection.
pub const FILE_DESCRIPTOR_SET: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/relief_v1_descriptor.bin"));
