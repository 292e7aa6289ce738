//! Command-line interface of the `mavtables` binary: options, finding and loading the
//! configuration, `--ast` and `--check`.

mod args;
mod commands;
mod run;
mod search;
mod text;

pub use args::{Options, parse};
pub use commands::run_tool;
pub use run::{Outcome, run};
pub use search::find_config;
pub use text::{help, version};
