//! Command-line interface of the `mavtables` binary: options (one reader, `arg_reader`,
//! for the main command and its subcommands), finding and loading the configuration or
//! building one from [`endpoints`], `--ast`, `--check`, and dispatching to the `inspect`
//! and `replay` subcommands and to `stats`.

pub(crate) mod arg_reader;
mod args;
mod commands;
#[doc(hidden)]
pub mod endpoints;
mod run;
mod search;
mod stats_args;
mod text;

pub use args::{Options, parse};
pub use commands::run_subcommand;
pub use run::{ENDPOINTS_SOURCE, Outcome, run};
pub use search::find_config;
pub use text::{help, version};
