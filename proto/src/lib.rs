//! Strider's gRPC contract, package `strider.v1` (`strider/v1/strider.proto`, documented
//! there), the generated code, and the conversions between wire messages and the model's
//! types, which validate through the parameter table.

/// The generated messages and services.
#[allow(clippy::all, missing_docs)]
pub mod v1 {
    tonic::include_proto!("strider.v1");
}

/// The encoded descriptor set of `strider.proto`, for gRPC reflection.
pub const FILE_DESCRIPTOR_SET: &[u8] =
    include_bytes!(concat!(env!("OUT_DIR"), "/strider_descriptor.bin"));

/// Protocol version a worker or client must present; a mismatch is refused.
pub const PROTOCOL_VERSION: u32 = 1;

pub mod convert;
pub mod secret;
