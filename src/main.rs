//! The `mavtables` binary: handles the command line, then runs the router.

use mavtables::cli::{Outcome, run};
use std::process::ExitCode;

fn main() -> ExitCode {
    let args = std::env::args_os()
        .map(|a| a.to_string_lossy().into_owned())
        .collect();
    match run(args, &mut std::io::stdout(), &mut std::io::stderr()) {
        Outcome::Exit(code) => ExitCode::from(code),
        Outcome::Run { path, config, .. } => {
            eprintln!(
                "mavtables: configuration {path} loaded ({} interfaces, {} chains); \
                 the router itself is not implemented yet",
                config.interfaces.len(),
                config.chains.len()
            );
            ExitCode::SUCCESS
        }
    }
}
