//! The configuration language: lexer, parser, `--ast` printer, located diagnostics and
//! the semantic model the router runs from.
//!
//! [`parse`] checks syntax only and gives the [`ast::Ast`] (what `--ast` prints);
//! [`load`] also checks meaning and gives a [`Config`]; [`read_keys`] then reads the
//! signing keys it names, [`check_signing_state`] checks its signing state file, and
//! [`check_record_path`] looks at the file a `record` path without `%` fields names.
//! [`read_source`] reads a configuration file, within [`CONFIG_FILE_LIMIT`].

pub mod ast;
pub mod claims;
pub mod diagnostic;
pub mod file;
pub mod keys;
pub mod lexer;
pub mod lines;
pub mod model;
pub mod net;
pub mod parser;
pub mod printer;
pub mod rate;
pub mod record_path;
pub mod recording;
pub mod semantics;
pub mod sockets;
pub mod stats;
pub mod suggest;

pub use diagnostic::{Diagnostic, Position};
pub use file::{FromFile, read_file};
pub use keys::{StateFileError, check_signing_state, read_keys};
pub use lines::LineIndex;
pub use model::*;
pub use parser::parse;
pub use printer::{print_ast, print_tree};
pub use rate::RateUnit;
pub use record_path::check_record_path;
pub use semantics::Loaded;

use crate::files::{FileError, read_regular};
use std::path::Path;

/// The largest configuration file read (16 MiB). A hand-written file with hundreds of
/// rules is tens of KiB; the limit leaves room for generated ones while keeping a
/// mistaken path (a log, a disk image) from being read into memory.
pub const CONFIG_FILE_LIMIT: u64 = 16 << 20;

/// The text of the configuration file at `path`, which must be a regular file (after
/// following symlinks) of at most [`CONFIG_FILE_LIMIT`] bytes; see
/// [`crate::files::read_regular`]. Bytes that are not UTF-8 become U+FFFD, which the
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
    pub const fn is_empty(&self) -> bool {
        self.end <= self.start
    }
}

/// Parses and checks a configuration source: the configuration and its warnings, or every
/// error found (a syntax error stops at the first one).
pub fn load(src: &str) -> Result<Loaded, Vec<Diagnostic>> {
    let ast = parse(src).map_err(|d| vec![d])?;
    semantics::analyse(&ast)
}

/// Renders `errors` one after the other, each located in `file`.
pub fn render_errors(file: &str, src: &str, errors: &[Diagnostic]) -> String {
    errors.iter().map(|d| d.render(file, src)).collect()
}
