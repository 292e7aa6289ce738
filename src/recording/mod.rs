//! Recording what flows, sans-IO: which frames are recorded (`filter`), the core's
//! bounded tap of them (`tap`), file names from the `record { path …; }` pattern
//! (`pattern`), the list of the recordings the router created, the only files it may
//! remove (`manifest`), which of them go when files are rotated or the disk fills
//! (`rotation`) and the counters (`counters`). The writer thread that puts records on
//! the disk is `src/io/recorder.rs`.
//!
//! A recording is a `.tlog`: each record is the time of arrival (8 bytes, big-endian
//! microseconds since the UNIX epoch) followed by the frame exactly as received.

pub(crate) mod counters;
pub(crate) mod filter;
pub(crate) mod manifest;
pub(crate) mod pattern;
pub(crate) mod rotation;
pub(crate) mod tap;

pub use counters::RecorderStats;
pub use filter::RecordFilter;
pub use manifest::Manifest;
pub use pattern::{FilePattern, LocalTime, PatternError};
pub use tap::Tap;
