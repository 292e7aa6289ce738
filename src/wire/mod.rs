//! The MAVLink wire format: frame header layout, frame checks, checksums, the streaming
//! frame parser, encoding and signatures. Pure functions over bytes; no I/O.

pub mod check;
pub mod crc;
pub mod encode;
pub(crate) mod frame;
pub(crate) mod header;
pub(crate) mod parser;
pub mod signing;
pub(crate) mod summary;

pub use check::{Checks, Rejection};
pub use frame::{ExactError, Frame, Signature};
pub use header::{HeaderError, HeaderRepr, Layout, Version};
pub use parser::{ParseEvents, Parser, ParserStats};
pub use summary::PacketSummary;

/// The exact bytes of one whole frame (as received, or as signed on its way out),
/// shared by every link that forwards it: queued and sent, never re-encoded.
pub type Packet = std::sync::Arc<[u8]>;
