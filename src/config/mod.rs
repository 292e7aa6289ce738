//! The configuration language: lexer, parser, `--ast` printer, located diagnostics and
//! the semantic model the router runs from. Filled in by the configuration issue.
