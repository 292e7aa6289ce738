//! The fixed texts of `--help` and `--version`.

/// The `--help` text: the original's option list (the first line names the program as it
/// was invoked), then the endpoints, the subcommands and how to get their own help.
pub fn help(argv0: &str) -> String {
    let usages: Vec<String> = (super::endpoints::KINDS.iter())
        .map(|(kind, form, _)| format!("{kind}:{form}"))
        .collect();
    // The examples line up two spaces after the longest form.
    let width = usages.iter().map(String::len).max().unwrap_or(0) + 2;
    let mut endpoints = String::new();
    for (usage, (kind, _, example)) in usages.iter().zip(super::endpoints::KINDS) {
        endpoints += &format!("  {usage:<width$}e.g. {kind}:{example}\n");
    }
    format!(
        "usage: {argv0}:\n\
         \x20 -h [ --help ]         show this help and exit\n\
         \x20 --config arg          configuration file to use\n\
         \x20 --ast                 print the configuration's syntax tree and exit\n\
         \x20 --check               check the configuration (syntax and meaning) and exit\n\
         \x20 --version             show version and license and exit\n\
         \x20 --loglevel arg        how much to log, from 0 (nothing) to 3 (every packet and decision)\n\
         \n\
         endpoints (instead of a configuration file: every packet is forwarded between them):\n\
         {endpoints}\
         \x20 IPv6 addresses go in brackets: udp-client:[::1]:14550\n\
         \n\
         subcommands ('mavtables SUBCOMMAND --help' shows a subcommand's options):\n\
         \x20 inspect FILE...       list, decode, summarise or check the frames of captures\n\
         \x20 replay FILE --to ...  send a capture's frames to a UDP or serial link\n\
         \x20 stats [OPTIONS]       a running router's rule and link counters (its stats block)\n\
         \n"
    )
}

/// The `--version` text.
pub fn version() -> String {
    format!(
        "mavtables {}\n\
         A MAVLink router and firewall, written in Rust.\n\
         License: GPL-2.0-or-later (GNU General Public License, version 2 or any later version).\n\
         It comes with no warranty; see the license for details.\n",
        env!("CARGO_PKG_VERSION")
    )
}
