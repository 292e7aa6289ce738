//! The configuration language: lexer, parser, `--ast` printer, located diagnostics and
//! the semantic model the router runs from.
//!
//! [`parse`] checks syntax only and gives the `ast::Ast` (what `--ast` prints);
//! [`load`] also checks meaning and gives a [`Config`]; [`read_keys`] then reads the
//! signing keys it names, [`check_signing_state`] checks its signing state file, and
//! [`check_record_path`] looks at the file a `record` path without `%` fields names, and
//! [`check_shared_path`] refuses a `record` path the flight log also writes under.
//! [`read_source`] reads a configuration file, within [`CONFIG_FILE_LIMIT`].

pub(crate) mod ast;
pub(crate) mod claims;
pub(crate) mod diagnostic;
pub(crate) mod file;
pub(crate) mod flight_log;
pub(crate) mod keys;
pub(crate) mod lexer;
pub(crate) mod lines;
pub(crate) mod model;
pub(crate) mod net;
pub(crate) mod parser;
pub(crate) mod paths;
pub(crate) mod printer;
pub(crate) mod rate;
pub(crate) mod record_path;
pub(crate) mod recording;
pub(crate) mod semantics;
pub(crate) mod sockets;
pub(crate) mod stats_block;
pub(crate) mod suggest;
mod values;
pub(crate) mod zenoh_block;

pub use diagnostic::{Diagnostic, Position};
pub use file::{FromFile, read_file};
pub use flight_log::{FlightLog, FlightLogMode, FlightLogProtocol};
pub use keys::{StateFileError, check_signing_state, read_keys, read_signing_state};
pub use lines::LineIndex;
pub use model::{
    Action, Chain, ChainId, Condition, Config, DEFAULT_MAX_PEERS, DEFAULT_STATE_DIRECTORY,
    DefaultAction, Heartbeat, Host, Interface, InterfaceGroup, InterfaceSigning, IpRange,
    PeerLimits, QueueBounds, Recording, Remote, Rule, SIGNING_STATE_FILE, SerialInterface,
    StatsEndpoint, TcpInterface, UdpInterface, WebSocketInterface, ZenohInterface, ZenohMode,
    ZenohReceive,
};
pub use parser::parse;
pub use printer::{print_ast, print_tree};
pub use rate::{Rate, RateUnit};
pub use record_path::{check_record_path, check_shared_path};
pub use semantics::Loaded;

use crate::files::{FileError, read_regular};
use std::path::Path;

/// The largest configuration file read (16 MiB). A hand-written file with hundreds of
/// rules is tens of KiB; the limit leaves room for generated ones while keeping a
/// mistaken path (a log, a disk image) from being read into memory.
pub const CONFIG_FILE_LIMIT: u64 = 16 << 20;

/// The text of the configuration file at `path`, which must be a regular file (after
/// following symlinks) of at most [`CONFIG_FILE_LIMIT`] bytes; see
/// `crate::files::read_regular`. Bytes that are not UTF-8 become U+FFFD, which the
/// lexer reports where they are.
pub fn read_source(path: &Path) -> Result<String, FileError> {
    let bytes = read_regular(path, CONFIG_FILE_LIMIT)?;
    Ok(String::from_utf8_lossy(&bytes).into_owned())
}

/// A byte range `start..end` in a configuration source.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Span {
    /// First byte.
    pub start: usize,
    /// One past the last byte.
    pub end: usize,
}

impl Span {
    /// The range `start..end`.
    pub const fn new(start: usize, end: usize) -> Self {
        Span { start, end }
    }

    /// True when the range holds no bytes.
    pub(crate) const fn is_empty(&self) -> bool {
        self.end <= self.start
    }
}

/// Parses and checks a configuration source: the configuration and its warnings, or every
/// error found (a syntax error stops at the first one).
/// `dialect` files are read relative to the working directory; see [`load_in`].
pub fn load(src: &str) -> Result<Loaded, Vec<Diagnostic>> {
    let ast = parse(src).map_err(|d| vec![d])?;
    semantics::analyse(&ast)
}

/// [`load`] for a configuration file in directory `dir` (relative `dialect` paths are
/// taken from there).
pub fn load_in(src: &str, dir: &Path) -> Result<Loaded, Vec<Diagnostic>> {
    let ast = parse(src).map_err(|d| vec![d])?;
    semantics::analyse_in(&ast, dir)
}

/// Renders `errors` one after the other, each located in `file`.
pub fn render_errors(file: &str, src: &str, errors: &[Diagnostic]) -> String {
    errors.iter().map(|d| d.render(file, src)).collect()
}
