//! The configuration language: lexer, parser, `--ast` printer, located diagnostics and
//! the semantic model the router runs from.
//!
//! [`parse`] checks syntax only and gives the [`ast::Ast`] (what `--ast` prints);
//! [`load`] also checks meaning and gives a [`Config`]; [`read_keys`] then reads the
//! signing keys it names.

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
pub mod recording;
pub mod semantics;
pub mod sockets;
pub mod stats;
pub mod suggest;

pub use diagnostic::{Diagnostic, Position};
pub use file::{FromFile, read_file};
pub use keys::read_keys;
pub use lines::LineIndex;
pub use model::*;
pub use parser::parse;
pub use printer::{print_ast, print_tree};
pub use semantics::Loaded;

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
