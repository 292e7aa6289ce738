//! The `flight_log` block in the configuration language: `--ast` in the original's
//! style, the model it loads to with its defaults, and located errors.

use super::config_text::{first_error, tree};
use mavtables::address::Address;
use mavtables::config::{self, FlightLog, FlightLogMode, FlightLogProtocol};

#[test]
fn the_block_prints_like_the_others() {
    assert_eq!(
        tree(
            "flight_log {\n    system 1;\n    source 245.190;\n    path /var/log/mavtables/%Y-%m-%d_%H-%M-%S;\n    mode while_armed;\n    protocol auto;\n    min_free_bytes 100000000;\n    max_files 50;\n}"
        ),
        ":001:  flight_log\n:002:  |  system 1\n:003:  |  source 245.190\n\
         :004:  |  path /var/log/mavtables/%Y-%m-%d_%H-%M-%S\n:005:  |  mode while_armed\n\
         :006:  |  protocol auto\n:007:  |  min_free_bytes 100000000\n:008:  |  max_files 50\n"
    );
    assert_eq!(tree("flight_log {}"), ":001:  flight_log\n");
}

#[test]
fn values_and_defaults() {
    let c = config::load(
        "flight_log { system 7; source 1.191; path /tmp/logs/%H; mode always; protocol ulog; max_files 3; min_free_bytes 0; }",
    )
    .expect("loads")
    .config;
    assert_eq!(
        c.flight_log,
        Some(FlightLog {
            system: 7,
            source: Address::new(1, 191),
            path: Some("/tmp/logs/%H".into()),
            mode: FlightLogMode::Always,
            protocol: FlightLogProtocol::Ulog,
            max_files: 3,
            min_free_bytes: 0,
        })
    );
    let d = config::load("flight_log {}").expect("loads").config;
    assert_eq!(d.flight_log, Some(FlightLog::with_defaults()));
    let d = FlightLog::with_defaults();
    assert_eq!(
        (d.system, d.source, d.mode, d.protocol, d.max_files),
        (
            1,
            Address::new(245, 190),
            FlightLogMode::WhileArmed,
            FlightLogProtocol::Auto,
            50
        )
    );
    assert_eq!(
        config::load("udp {}").expect("loads").config.flight_log,
        None
    );
}

#[test]
fn errors_are_located() {
    for (src, want) in [
        (
            "flight_log { mode sometimes; }",
            "f:1:19: expected 'always' or 'while_armed', found 'sometimes'",
        ),
        (
            "flight_log { protocol mavlink; }",
            "f:1:23: expected 'auto', 'dataflash' or 'ulog', found 'mavlink'",
        ),
        (
            "flight_log { source 245.0; }",
            "f:1:21: expected an address like 245.190, found '245.0'",
        ),
        (
            "flight_log { system 0; }",
            "f:1:21: system id (0) is outside of the allowed range (1 - 255)",
        ),
        (
            "flight_log { path /x/%Q; }",
            "f:1:22: unknown directive '%Q'",
        ),
        (
            "flight_log { max_filez 3; }",
            "f:1:14: unsupported statement",
        ),
        (
            "flight_log {}\nflight_log {}",
            "f:2:1: only one 'flight_log' block is allowed",
        ),
        (
            "flight_log { min_free_bytes 100MB; }",
            "f:1:29: expected a valid number of bytes",
        ),
    ] {
        assert_eq!(first_error(src), want, "for {src:?}");
    }
}
