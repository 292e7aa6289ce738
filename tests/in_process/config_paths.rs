//! `dedup`, `group` and `heartbeat` in the configuration language: `--ast` in the
//! original's style, the model they load to, and located errors.

use std::time::Duration;

use super::config_text::{first_error, tree};
use mavtables::config::{self, Heartbeat, InterfaceGroup};

#[test]
fn the_ast_prints_each_statement_with_its_raw_value() {
    assert_eq!(
        tree("dedup\n  500ms;\nudp { port 1; group radios; }\nserial { device d; group radios; }"),
        ":002:  dedup 500ms\n:003:  udp\n:003:  |  port 1\n:003:  |  group radios\n\
         :004:  serial\n:004:  |  device d\n:004:  |  group radios\n"
    );
    assert_eq!(
        tree("heartbeat {\n    system 1;\n    component 191;\n    interval 1s;\n}"),
        ":001:  heartbeat\n:002:  |  system 1\n:003:  |  component 191\n:004:  |  interval 1s\n"
    );
    assert_eq!(tree("heartbeat {}"), ":001:  heartbeat\n");
    // Syntax only: an out-of-range value prints raw.
    assert_eq!(tree("dedup 99min;"), ":001:  dedup 99min\n");
}

#[test]
fn values_and_defaults() {
    let c = config::load(
        "dedup 250ms;\nudp { port 1; group a; }\ntcp { port 2; group a; }\nudp { port 3; }\nheartbeat { interval 2s; }",
    )
    .expect("loads")
    .config;
    assert_eq!(c.dedup, Some(Duration::from_millis(250)));
    assert_eq!(
        c.groups,
        vec![
            InterfaceGroup {
                interface: 0,
                name: "a".into()
            },
            InterfaceGroup {
                interface: 1,
                name: "a".into()
            },
        ]
    );
    assert_eq!(
        c.heartbeat,
        Some(Heartbeat {
            system: 1,
            component: 191,
            interval: Duration::from_secs(2)
        })
    );
    let plain = config::load("udp {}").expect("loads").config;
    assert_eq!(
        (plain.dedup, plain.heartbeat, plain.groups.len()),
        (None, None, 0)
    );
    let lonely = config::load("udp { group x; }").expect("loads");
    assert!(
        lonely
            .warnings
            .iter()
            .any(|w| w.contains("group 'x' has one interface"))
    );
}

#[test]
fn errors_are_located() {
    for (src, want) in [
        ("dedup;", "f:1:6: expected a duration, e.g. 500ms or 1s"),
        (
            "dedup 5h;",
            "f:1:7: unknown unit 'h' in duration '5h': use ms, s or min",
        ),
        (
            "dedup 0ms;",
            "f:1:7: dedup window (0ms) is outside of the allowed range (1ms - 10s)",
        ),
        (
            "dedup 1s;\ndedup 2s;",
            "f:2:1: only one 'dedup' statement is allowed",
        ),
        ("dedup 1s", "f:1:9: expected end of statement ';' character"),
        (
            "heartbeat { system 0; }",
            "f:1:20: system id (0) is outside of the allowed range (1 - 255)",
        ),
        (
            "heartbeat { component 256; }",
            "f:1:23: component id (256) is outside of the allowed range (1 - 255)",
        ),
        (
            "heartbeat { interval 5ms; }",
            "f:1:22: heartbeat interval (5ms) is outside of the allowed range (10ms - 3600s)",
        ),
        ("heartbeat { sytem 1; }", "f:1:13: unsupported statement"),
        (
            "heartbeat {}\nheartbeat {}",
            "f:2:1: only one 'heartbeat' block is allowed",
        ),
        ("udp { group; }", "f:1:12: expected a group name"),
        (
            "udp { group a; group b; }",
            "f:1:22: an interface belongs to one group only",
        ),
        ("stats { group a; }", "f:1:9: unsupported statement"),
        ("queue { group a; }", "f:1:9: unsupported statement"),
    ] {
        assert_eq!(first_error(src), want, "{src}");
    }
}
