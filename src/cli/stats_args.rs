//! The command line of `mavtables stats` (read by the shared [`super::arg_reader`]
//! reader): where the router's statistics endpoint is (`--url`, or the `stats` block of
//! the configuration the router runs from), and `--watch`.

use std::io::{IsTerminal, Write};
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use super::arg_reader::{Arg, ArgReader, OptionSpec};
use super::find_config;
use crate::commands::stats::render::View;
use crate::commands::stats::{self, Endpoint};
use crate::config::{self, render_errors};

const USAGE: &str = "\
usage: mavtables stats [--config FILE | --url http://HOST:PORT] [--top N] [--filter TEXT] [--watch]
  Asks a running router for its statistics and prints every chain and rule with the
  packets, bytes and decisions it counted (like iptables -L -v), then a table of links:
  the troubled first (state drops, gaps or silent), then the busiest.
  --config FILE     the router's configuration: its stats block says where to ask
                    (without --config or --url, the file is searched for as the
                    router does: $MAVTABLES_CONFIG_PATH, ./.mavtablesrc, ...)
  --url URL         ask http://HOST:PORT directly
  --top N           at most N links (and N lossy sources), saying how many are hidden
  --filter TEXT     only links whose name, interface or addresses contain TEXT
                    (and sources that do), ignoring case
  --watch           redraw every second, like top, until Ctrl-C
  A link's state: drops (a frame of it was dropped since the router started), gaps (a
  source learned on it lost frames), silent (nothing received over the last 5 samples
  of its history, 5 s by default), else ok.
";

/// The options of `stats`, as read by the shared reader.
const OPTIONS: &[OptionSpec] = &[
    OptionSpec::flag("help"),
    OptionSpec::value("config"),
    OptionSpec::value("url"),
    OptionSpec::flag("watch"),
    OptionSpec::value("top"),
    OptionSpec::value("filter"),
];

/// Runs `mavtables stats ARGS`; the exit status, or the error line to print.
pub(super) fn run_stats(
    args: &[String],
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> Result<u8, String> {
    let mut config = None;
    let mut url = None;
    let mut watch = false;
    let mut view = View::default();
    let mut reader = ArgReader::new(args.iter().cloned(), &[OPTIONS]);
    while let Some(arg) = reader.next_arg()? {
        match arg {
            Arg::Option { name: "help", .. } => {
                let _ = out.write_all(USAGE.as_bytes());
                return Ok(0);
            }
            Arg::Option {
                name: "config",
                value,
            } => config = value,
            Arg::Option { name: "url", value } => url = value,
            Arg::Option { name: "watch", .. } => watch = true,
            Arg::Option { name: "top", value } => {
                let text = value.unwrap_or_default();
                view.top = Some(text.parse().map_err(|_| {
                    format!("--top '{text}': expected a number of rows, e.g. --top 20")
                })?);
            }
            Arg::Option {
                name: "filter",
                value,
            } => view.filter = value.filter(|f| !f.is_empty()),
            Arg::Option { .. } => {}
            Arg::Positional(extra) => {
                let _ = err.write_all(USAGE.as_bytes());
                return Err(format!("unexpected argument '{extra}'"));
            }
        }
    }
    let endpoint = match (config, url) {
        (Some(_), Some(_)) => return Err("use either --config or --url".into()),
        (None, Some(url)) => Endpoint::from_url(&url)?,
        (config, None) => from_config(config.as_deref(), err)?,
    };
    if !watch {
        stats::show(&endpoint, &view, out)?;
        return Ok(0);
    }
    // Ctrl-C (and SIGTERM) end the loop, which puts the terminal back before exiting 0.
    let stop = Arc::new(AtomicBool::new(false));
    for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(signal, Arc::clone(&stop))
            .map_err(|e| format!("cannot catch Ctrl-C: {e}"))?;
    }
    let terminal = std::io::stdout().is_terminal();
    match stats::watch(&endpoint, &view, out, terminal, &stop) {
        Ok(()) => Ok(0),
        // The reader went away (`| head`): stop quietly, as command-line tools do.
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(0),
        Err(e) => Err(format!("writing output: {e}")),
    }
}

/// The endpoint named by the `stats` block of the configuration at `explicit`, or of the
/// one the router would find without `--config`.
fn from_config(explicit: Option<&str>, err: &mut dyn Write) -> Result<Endpoint, String> {
    let path = find_config(explicit, |k| std::env::var(k).ok(), Path::exists).ok_or_else(|| {
        match explicit {
            Some(p) => format!("configuration file {p} does not exist"),
            None => "mavtables could not locate a configuration file; name it with --config or ask --url http://HOST:PORT".into(),
        }
    })?;
    let src = config::read_source(Path::new(&path))
        .map_err(|e| format!("configuration file {path} {e}"))?;
    let loaded = match config::load(&src) {
        Ok(l) => l,
        Err(errors) => {
            let _ = err.write_all(render_errors(&path, &src, &errors).as_bytes());
            return Err(format!("{path} is not a valid configuration"));
        }
    };
    match &loaded.config.stats {
        None => Err(format!(
            "{path} has no stats block, so the router serves no statistics; add `stats {{ port 9100; }}` and restart it"
        )),
        Some(block) if block.port == 0 => Err(format!(
            "the stats block of {path} says port 0 (any free port): ask --url http://HOST:PORT with the port the router said at start"
        )),
        Some(block) => Ok(Endpoint::of_listener(block.address, block.port)),
    }
}
