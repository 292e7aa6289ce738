//! The MAVLink wire format: frame layout, checksums, the streaming frame parser,
//! encoding and signatures. Pure functions over bytes; no I/O.

pub mod crc;
pub mod encode;
pub mod frame;
pub mod parser;
pub mod signing;

pub use frame::{ExactError, Frame, Rejection, Signature, Version};
pub use parser::{ParseEvents, Parser, ParserStats};
