//! Command-line interface of the `mavtables` binary: options (one reader, [`options`],
//! for the main command and its subcommands), finding and loading the configuration,
//! `--ast`, `--check`, and dispatching to the `inspect` and `replay` subcommands.

mod args;
mod commands;
pub mod options;
mod run;
mod search;
mod text;

pub use args::{Options, parse};
pub use commands::run_subcommand;
pub use run::{Outcome, run};
pub use search::find_config;
pub use text::{help, version};
