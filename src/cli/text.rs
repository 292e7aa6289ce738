//! The fixed texts of `--help` and `--version`.

/// The `--help` text; the first line names the program as it was invoked.
pub fn help(argv0: &str) -> String {
    format!(
        "usage: {argv0}:\n\
         \x20 -h [ --help ]         show this help and exit\n\
         \x20 --config arg          configuration file to use\n\
         \x20 --ast                 print the configuration's syntax tree and exit\n\
         \x20 --check               check the configuration (syntax and meaning) and exit\n\
         \x20 --version             show version and license and exit\n\
         \x20 --loglevel arg        how much to log, from 0 (nothing) to 3 (every packet)\n\
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
