//! Property: any input gives either a configuration or located errors, never a panic, and
//! every error position lies inside the input and renders.

use mavtables::config::{self, parse, print_ast};
use proptest::prelude::*;

/// Pieces of the language, so random inputs get deep into the grammar.
const PIECES: &[&str] = &[
    "udp",
    "serial",
    "chain",
    "default",
    "default_action",
    "accept",
    "reject",
    "call",
    "goto",
    "with",
    "priority",
    "if",
    "from",
    "to",
    "port",
    "address",
    "max_bitrate",
    "device",
    "baudrate",
    "flow_control",
    "preload",
    "queue",
    "tcp",
    "connect",
    "max_peers",
    "allow",
    "signing_key",
    "allow_unsigned",
    "signing_state",
    "signed",
    "unsigned",
    "/etc/k.key",
    "[",
    "]",
    "::",
    "fd00::7",
    "[::1]:5760",
    "localhost:14550",
    "10.0.0.0/8",
    "_",
    "link_bytes",
    "total_bytes",
    "312",
    "4096",
    "yes",
    "no",
    "PING",
    "HEARTBEAT",
    "x",
    "{",
    "}",
    ";",
    " ",
    "\n",
    "\t",
    "#",
    ".",
    ":",
    "/",
    "\\",
    "-",
    "+",
    "0",
    "1",
    "255",
    "256",
    "14500",
    "99999999999999999999999",
    "1.1",
    "127.0.0.1",
    "é",
    "\r\n",
    "record",
    "path",
    "max_file_bytes",
    "max_files",
    "min_free_bytes",
    "only",
    "%Y",
    "%q",
    "%",
    "/var/log/%H.tlog",
    "websocket",
    "origin",
    "http://",
    "HTTPS://",
    "localhost",
    ":8080",
    "?",
    "@",
];

fn check(src: &str) {
    match config::load(src) {
        Ok(loaded) => {
            let c = loaded.config;
            assert!(c.default_chain.0 < c.chains.len());
            assert_eq!(c.chain(c.default_chain).name, "default");
            if let Some(r) = &c.record {
                assert!(r.max_file_bytes >= config::Recording::MIN_FILE_BYTES);
                let path = r.path_pattern(|_| None);
                assert!(
                    mavtables::recording::FilePattern::parse(&path).is_ok(),
                    "{path}"
                );
            }
            for iface in &c.interfaces {
                if let config::Interface::WebSocket(w) = iface {
                    for o in &w.origins {
                        // Lower case, a scheme, a host, no path.
                        assert_eq!(*o, o.to_ascii_lowercase());
                        let rest = o
                            .strip_prefix("http://")
                            .or_else(|| o.strip_prefix("https://"))
                            .expect("a scheme");
                        assert!(
                            !rest.is_empty() && !rest.contains(['/', '?', '#', '@']),
                            "{o}"
                        );
                    }
                }
            }
        }
        Err(errors) => {
            assert!(!errors.is_empty());
            for e in &errors {
                assert!(
                    e.span.start <= src.len() && e.span.end <= src.len(),
                    "{e:?}"
                );
                let rendered = e.render("p", src);
                assert!(rendered.starts_with("p:"));
            }
        }
    }
    if let Ok(ast) = parse(src) {
        assert!(print_ast(&ast, "p").starts_with("===== p =====\n"));
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn any_origin_value_is_taken_or_refused_located(value in "[ -~]{0,40}") {
        check(&format!("websocket {{ origin {value}; }}"));
        check(&format!("websocket {{ origin http://{value}; }}"));
    }

    #[test]
    fn arbitrary_text_never_panics(src in any::<String>()) {
        check(&src);
    }

    #[test]
    fn grammar_soup_never_panics(parts in prop::collection::vec(prop::sample::select(PIECES), 0..60)) {
        let src: String = parts.concat();
        check(&src);
        let spaced = parts.join(" ");
        check(&spaced);
    }

    #[test]
    fn valid_rules_round_trip_through_the_ast(
        action in prop::sample::select(&["accept", "reject", "call c", "goto c"][..]),
        prio in prop::option::of(any::<i32>()),
        signed in prop::option::of(any::<bool>()),
        ty in prop::option::of(prop::sample::select(&["PING", "HEARTBEAT", "GPS_STATUS"][..])),
        from in prop::option::of((any::<u8>(), any::<u8>(), 0u8..=16)),
        to in prop::option::of((any::<u8>(), any::<u8>(), 0u8..=8)),
    ) {
        let mut rule = action.to_string();
        if let Some(p) = prio { rule += &format!(" with priority {p}"); }
        if signed.is_some() || ty.is_some() || from.is_some() || to.is_some() {
            rule += " if";
            if let Some(s) = signed { rule += if s { " signed" } else { " unsigned" }; }
            if let Some(t) = ty { rule += &format!(" {t}"); }
            if let Some((s, c, b)) = from { rule += &format!(" from {s}.{c}/{b}"); }
            if let Some((s, c, b)) = to { rule += &format!(" to {s}.{c}\\{b}"); }
        }
        let src = format!("chain default {{ {rule}; }}\nchain c {{ accept; }}");
        // The same condition records: `only if ...;` takes the rules' syntax.
        if let Some((_, cond)) = rule.split_once(" if ") {
            let record = format!("record {{ only if {cond}; only if from 1.1; }}");
            let loaded = config::load(&record);
            prop_assert!(loaded.is_ok(), "{record}");
            if let Ok(l) = loaded {
                let r = l.config.record.expect("record");
                prop_assert_eq!(r.only.len(), 2);
                prop_assert_eq!(r.only[0].signed, signed);
            }
        }
        let loaded = config::load(&src);
        prop_assert!(loaded.is_ok(), "{src}");
        if let Ok(l) = loaded {
            let c = l.config;
            prop_assert_eq!(c.chain(c.default_chain).rules[0].condition.signed, signed);
        }
    }
}
