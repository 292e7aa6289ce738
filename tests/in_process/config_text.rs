//! What the configuration tests read off a text: its `--ast` tree, or the first line of
//! its first located error.

use mavtables::config::{self, parse, print_tree};

/// The `--ast` tree of `src` (panics with the rendered error if it does not parse).
pub fn tree(src: &str) -> String {
    match parse(src) {
        Ok(ast) => print_tree(&ast),
        Err(d) => panic!("{}", d.render("t", src)),
    }
}

/// The first line of the first error `src` loads with, as `f:LINE:COL: message`
/// (panics if it loads).
pub fn first_error(src: &str) -> String {
    match config::load(src) {
        Ok(_) => panic!("expected an error for {src:?}"),
        Err(e) => e[0]
            .render("f", src)
            .lines()
            .next()
            .unwrap_or_default()
            .to_string(),
    }
}
