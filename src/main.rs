//! The `mavtables` binary: handles the command line, then runs the router.

use std::process::ExitCode;

use mavtables::cli::{ENDPOINTS_SOURCE, Outcome, run};

fn main() -> ExitCode {
    let args = std::env::args_os()
        .map(|a| a.to_string_lossy().into_owned())
        .collect();
    match run(args, &mut std::io::stdout(), &mut std::io::stderr()) {
        Outcome::Exit(code) => ExitCode::from(code),
        Outcome::Run {
            config,
            keys,
            options,
            path,
        } => {
            // SIGHUP reads the file again; endpoints have none.
            let source = (path != ENDPOINTS_SOURCE).then_some(path.as_str());
            ExitCode::from(mavtables::io::run(&config, &keys, options.loglevel, source))
        }
    }
}
