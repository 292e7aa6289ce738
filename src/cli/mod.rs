//! Command-line interface of the `mavtables` binary: options, finding and loading the
//! configuration, `--ast` and `--check`.

mod args;
mod run;
mod search;
mod text;
mod tools;

pub use args::{Options, parse};
pub use run::{Outcome, run};
pub use search::find_config;
pub use text::{help, version};
pub use tools::run_tool;
