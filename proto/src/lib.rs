//! Strider's gRPC contract, package `strider.v1`.
//!
//! The worker and client protocols (and their generated code) land with the service issue;
//! this crate already fixes the protocol version both sides exchange.

/// Protocol version a worker or client must present; a mismatch is refused.
pub const PROTOCOL_VERSION: u32 = 1;
