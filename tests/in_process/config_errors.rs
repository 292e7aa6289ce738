//! Every class of configuration error: exact position (1-based line and column) and text.

use mavtables::config::{self, Diagnostic};

/// The first line of the first error, rendered for a file named `f`.
fn first(src: &str) -> String {
    let errors: Vec<Diagnostic> = match config::load(src) {
        Ok(_) => panic!("expected an error for {src:?}"),
        Err(e) => e,
    };
    let rendered = errors[0].render("f", src);
    rendered.lines().next().unwrap_or_default().to_string()
}

fn all(src: &str) -> String {
    match config::load(src) {
        Ok(_) => panic!("expected an error for {src:?}"),
        Err(e) => config::render_errors("f", src, &e),
    }
}

#[track_caller]
fn check(src: &str, want: &str) {
    assert_eq!(first(src), format!("f:{want}"), "source: {src:?}");
}

#[test]
fn statements_and_blocks() {
    check("invalid", "1:1: unsupported statement");
    check("invalid;", "1:1: unsupported statement");
    check(
        "default_action accept",
        "1:22: expected end of statement ';' character",
    );
    check(
        "default_action invalid;",
        "1:16: expected 'accept' or 'reject'",
    );
    check("default_action;", "1:15: expected 'accept' or 'reject'");
    check("udp }", "1:5: expected opening brace '{'");
    check("udp", "1:4: expected opening brace '{'");
    check("udp {", "1:6: expected closing brace '}'");
    check("serial {", "1:9: expected closing brace '}'");
    check("", "1:1: expected at least one valid statement or block");
    check(
        "  \n\t\n",
        "1:1: expected at least one valid statement or block",
    );
    check(
        "# only a comment",
        "1:1: expected at least one valid statement or block",
    );
}

#[test]
fn stray_text() {
    check("udp {}\n}", "2:1: expected a statement or block, found '}'");
    check(";", "1:1: expected a statement or block, found ';'");
    check(
        "udp {} 42;",
        "1:8: expected a statement or block, found '42'",
    );
    check("udp { ; }", "1:7: expected a statement or '}', found ';'");
    check("chain a { ; }", "1:11: expected a valid rule");
    check(
        "udp {} é",
        "1:8: the character 'é' (U+00E9) is not part of the language: outside comments it is written in ASCII",
    );
}

#[test]
fn missing_semicolon_points_where_it_belongs() {
    check(
        "udp {\n    port 14500\n}",
        "2:15: expected end of statement ';' character",
    );
    check(
        "udp { port 14500 }",
        "1:18: expected end of statement ';' character",
    );
    check(
        "chain default {\n    accept\n}",
        "2:11: expected end of statement ';' character",
    );
    check(
        "chain default { reject }",
        "1:24: expected end of statement ';' character",
    );
    check("foo bar;", "1:1: unsupported statement");
}

#[test]
fn udp_values() {
    check(
        "udp {\n    port a35;\n}",
        "2:10: expected a valid port number",
    );
    check("udp {\n    port;\n}", "2:9: expected a valid port number");
    check("udp { ports 1; }", "1:7: unsupported statement");
    check(
        "udp { port 70000; }",
        "1:12: port number (70000) is outside of the allowed range (0 - 65535)",
    );
    check(
        "udp {\n    address 127.0.0.;\n}",
        "2:21: expected a valid IP address",
    );
    check(
        "udp {\n    address 127.a.0.1;\n}",
        "2:17: expected a valid IP address",
    );
    // A ':' makes it an IPv6 address, checked as a whole.
    check(
        "udp {\n    address 127:0:0:1;\n}",
        "2:13: expected a valid IP address",
    );
    assert!(
        all("udp { address 10.0.0.1:80; }")
            .contains("note: an address is written without a port here")
    );
    check(
        "udp {\n    address;\n}",
        "2:12: expected a valid IP address",
    );
    check(
        "udp {\n    address 127.0.0.1.;\n}",
        "2:22: expected end of statement ';' character",
    );
    check(
        "udp { address 10.300.0.1; }",
        "1:18: Address octet (300) is outside of the allowed range (0 - 255).",
    );
    check(
        "udp { max_bitrate fast; }",
        "1:19: expected a valid bitrate",
    );
    check(
        "udp { max_bitrate 99999999999999999999; }",
        "1:19: bitrate (99999999999999999999) is outside of the allowed range (0 - 18446744073709551615)",
    );
}

#[test]
fn serial_values() {
    check(
        "serial {\n    device;\n}",
        "2:11: expected a valid serial port device name",
    );
    check(
        "serial {\n    device ttyUSB0\n}",
        "2:19: expected end of statement ';' character",
    );
    check(
        "serial { baudrate x; device a; }",
        "1:19: expected a valid baud rate",
    );
    check(
        "serial { device a; baudrate 0; }",
        "1:29: baud rate (0) is outside of the allowed range (1 - 4294967295)",
    );
    check(
        "serial { device a; baudrate 4294967296; }",
        "1:29: baud rate (4294967296) is outside of the allowed range (1 - 4294967295)",
    );
    check(
        "serial {\n    flow_control maybe;\n}",
        "2:18: expected 'yes' or 'no'",
    );
    check(
        "serial {\n    flow_control;\n}",
        "2:17: expected 'yes' or 'no'",
    );
    check(
        "serial { device a; preload 1; }",
        "1:29: expected a valid MAVLink address",
    );
    check(
        "serial { device a; preload x; }",
        "1:28: expected a valid MAVLink address",
    );
    check(
        "serial { device a; preload 256.1; }",
        "1:28: System ID (256) is outside of the allowed range (0 - 255).",
    );
    check(
        "serial { device a; preload 1.256; }",
        "1:30: Component ID (256) is outside of the allowed range (0 - 255).",
    );
    check("serial { baudrate 57600; }", "1:1: missing device string");
    check("serial { port 1; }", "1:10: unsupported statement");
    assert!(all("serial { port 1; }").contains("note: 'port' belongs in a 'udp' or 'tcp' block"));
    assert!(all("serial { boadrate 1; }").contains("note: did you mean 'baudrate'?"));
}

#[test]
fn chains_and_rules() {
    check("chain {}", "1:7: expected a valid chain name");
    check("chain 1nv@l1d {}", "1:7: expected a valid chain name");
    check(
        "chain default {\n    invalid;\n}",
        "2:5: expected a valid rule",
    );
    check(
        "chain default { acceptif HEARTBEAT; }",
        "1:17: expected a valid rule",
    );
    check(
        "chain default { call; }",
        "1:21: expected a valid chain name",
    );
    check(
        "chain default {\n    accept if;\n}",
        "2:14: condition is empty or invalid",
    );
    check(
        "chain default {\n    accept if ping;\n}",
        "2:15: condition is empty or invalid",
    );
    check(
        "chain default { accept with; }",
        "1:28: 'with' keyword must be followed by the 'priority' keyword",
    );
    check(
        "chain default { accept with priority; }",
        "1:37: expected priority level",
    );
    check(
        "chain default { accept with priority - 1; }",
        "1:38: expected priority level",
    );
    check(
        "chain default { accept with priority 2147483648; }",
        "1:38: priority level (2147483648) is outside of the allowed range (-2147483648 - 2147483647)",
    );
    check(
        "chain default { accept with priority -2147483649; }",
        "1:38: priority level (-2147483649) is outside of the allowed range (-2147483648 - 2147483647)",
    );
    check(
        "chain default { accept if to 1.1 from 2.2; }",
        "1:34: expected end of statement ';' character",
    );
    check(
        "chain default { accept if from 1.1 with priority 3; }",
        "1:36: expected end of statement ';' character",
    );
}

#[test]
fn subnets() {
    check(
        "chain default { accept if from 192; }",
        "1:35: expected a valid MAVLink subnet",
    );
    check(
        "chain default { accept if from 192:255.255; }",
        "1:35: expected a valid MAVLink subnet",
    );
    check(
        "chain default { accept if from 1.1:255; }",
        "1:39: expected a valid MAVLink address",
    );
    check(
        "chain default { accept if to 1.1/; }",
        "1:34: expected a valid MAVLink subnet",
    );
    check(
        "chain default { accept if to; }",
        "1:29: expected a valid MAVLink subnet",
    );
    check(
        "chain default { accept if from 256.1; }",
        "1:32: System ID (256) is outside of the allowed range (0 - 255).",
    );
    check(
        "chain default { accept if from 1.1:1.999; }",
        "1:38: Component ID (999) is outside of the allowed range (0 - 255).",
    );
    check(
        "chain default { accept if to 1.1/17; }",
        "1:34: Forward slash mask (17) is outside of allowed range (0 - 16).",
    );
    check(
        "chain default { accept if to 1.1\\9; }",
        "1:34: Backslash mask (9) is outside of allowed range (0 - 8).",
    );
}

#[test]
fn names_and_references() {
    check(
        "chain default { call nowhere; }",
        "1:22: chain 'nowhere' is not defined",
    );
    assert!(
        all("chain default { goto ohter; }\nchain other {}")
            .contains("note: did you mean 'other'?")
    );
    check(
        "chain default { call default; }",
        "1:22: cannot 'call' the default chain",
    );
    check(
        "chain a {}\nchain default { goto default; }",
        "2:22: cannot 'goto' the default chain",
    );
    check(
        "chain default { accept if NOT_A_MSG; }",
        "1:27: Invalid packet name (\"NOT_A_MSG\").",
    );
    assert!(
        all("chain default { accept if HEARTBEET; }").contains("note: did you mean 'HEARTBEAT'?")
    );
    assert!(all("chain default { accept if heartbeat; }").contains("upper case: 'HEARTBEAT'"));
}

#[test]
fn cycles_name_the_chains_and_lines() {
    let src = "chain default { call a; }\nchain a {\n    goto b if HEARTBEAT;\n}\nchain b {\n    call a;\n}\n";
    assert_eq!(
        all(src),
        "f:3:10: call/goto cycle: a -> b -> a\n    goto b if HEARTBEAT;\n         ^\n\
         note: line 3: chain 'a' goes to 'b'\nnote: line 6: chain 'b' calls 'a'\n"
    );
    check("chain a { call a; }", "1:16: call/goto cycle: a -> a");
}

#[test]
fn every_semantic_error_is_reported_in_file_order() {
    let src = "udp { port 70000; }\nchain default { call x; accept if NOPE; }\n";
    let text = all(src);
    let firsts: Vec<&str> = text.lines().filter(|l| l.starts_with("f:")).collect();
    assert_eq!(
        firsts,
        [
            "f:1:12: port number (70000) is outside of the allowed range (0 - 65535)",
            "f:2:22: chain 'x' is not defined",
            "f:2:35: Invalid packet name (\"NOPE\").",
        ]
    );
}

#[test]
fn full_rendering_has_source_line_and_caret() {
    assert_eq!(
        all("udp {\n\tport a35;\n}\n"),
        "f:2:7: expected a valid port number\n\tport a35;\n\t     ^^^\n"
    );
}

#[test]
fn two_interfaces_on_one_port_or_device() {
    check(
        "udp { port 14550; }\nudp { port 14550; address 127.0.0.1; }",
        "2:1: udp interface 127.0.0.1:14550 clashes with the udp interface on line 1 (0.0.0.0:14550)",
    );
    check(
        "udp { port 14550; address 10.0.0.1; }\n\nudp { address 10.0.0.1; port 14550; }",
        "3:1: udp interface 10.0.0.1:14550 clashes with the udp interface on line 1 (10.0.0.1:14550)",
    );
    check(
        "serial { device /dev/ttyUSB0; }\nserial { device /dev/ttyUSB0; baudrate 57600; }",
        "2:1: serial device '/dev/ttyUSB0' is already used by the serial interface on line 1",
    );
    // Different addresses, different ports, port 0 (any free port): no clash.
    for ok in [
        "udp { port 14550; address 10.0.0.1; }\nudp { port 14550; address 10.0.0.2; }",
        "udp { port 14550; }\nudp { port 14551; }",
        "udp { port 0; }\nudp { port 0; }",
        "serial { device /dev/ttyUSB0; }\nserial { device /dev/ttyUSB1; }",
    ] {
        assert!(config::load(ok).is_ok(), "{ok}");
    }
    // The whole message: the offending line, a caret and what to do.
    let text = all("serial { device /dev/ttyS0; }\nserial { device /dev/ttyS0; }\n");
    assert!(text.contains("serial { device /dev/ttyS0; }"), "{text}");
    assert!(text.contains("one serial block only"), "{text}");
}

#[test]
fn queue_block() {
    check("queue", "1:6: expected opening brace '{'");
    check("queue {", "1:8: expected closing brace '}'");
    check(
        "queue { link_bytes; }",
        "1:19: expected a valid number of bytes",
    );
    check(
        "queue { total_bytes -1; }",
        "1:21: expected a valid number of bytes",
    );
    check(
        "queue { link_bytes 4096 }",
        "1:25: expected end of statement ';' character",
    );
    check(
        "queue {\n    link_bytes 4096\n}",
        "2:20: expected end of statement ';' character",
    );
    check("queue { port 1; }", "1:9: unsupported statement");
    check(
        "queue { link_bytes 311; }",
        "1:20: link_bytes (311) is outside of the allowed range (312 - 1099511627776)",
    );
    check(
        "queue { total_bytes 1099511627777; }",
        "1:21: total_bytes (1099511627777) is outside of the allowed range (312 - 1099511627776)",
    );
    check(
        "queue { total_bytes 99999999999999999999999; }",
        "1:21: total_bytes (99999999999999999999999) is outside of the allowed range (312 - 1099511627776)",
    );
    check(
        "queue { total_bytes 4096; link_bytes 8192; }",
        "1:21: total_bytes (4096) must be at least link_bytes (8192)",
    );
    check(
        "queue { link_bytes 4096; }\nudp {}\nqueue {}",
        "3:1: only one 'queue' block is allowed",
    );
    assert!(all("queue {}\nqueue {}").contains("note: the first 'queue' block is on line 1"),);
    assert!(
        all("queue { link_bytes 1; }")
            .contains("note: a queue needs room for one largest frame (280 bytes)")
    );
    assert!(all("queue { linkbytes 1; }").contains("note: did you mean 'link_bytes'?"));
    assert!(
        all("udp { total_bytes 4096; }").contains("note: 'total_bytes' belongs in a 'queue' block")
    );
}

/// A character the language never uses is named, wherever it stops the parser: in a name
/// (`dëfault` is not the name `d` followed by a missing brace), in a keyword, after a
/// subnet, and an ASCII control character alike; what was expected follows as a note.
#[test]
fn a_stray_character_is_named() {
    let name = "the character 'ë' (U+00EB) cannot be part of a name: names are ASCII letters, digits and '_'";
    assert_eq!(
        all("chain dëfault {\n    accept;\n}\n"),
        format!("f:1:8: {name}\nchain dëfault {{\n       ^\nnote: expected opening brace '{{'\n")
    );
    check(
        "udp { pört 14500; }",
        &format!("1:8: {}", name.replace("'ë' (U+00EB)", "'ö' (U+00F6)")),
    );
    check(
        "chain default {\n    accept if HEARTBËAT;\n}",
        "2:21: the character 'Ë' (U+00CB) cannot be part of a name: names are ASCII letters, digits and '_'",
    );
    check(
        "chain default {\n    accept if HEARTBEAT from 1.ë;\n}",
        "2:32: the character 'ë' (U+00EB) is not part of the language: outside comments it is written in ASCII",
    );
    check(
        "default_action \u{1}accept;",
        "1:16: the character '\\u{1}' (U+0001) is not part of the language: outside comments it is written in ASCII",
    );
    // Comments may hold anything.
    assert!(config::load("# dëfault\ndefault_action accept;\n").is_ok());
}

/// A rule naming a message of a million characters gets its error at once (the "did you
/// mean" search only looks at names of about its length, and none is that long), and the
/// rendered error stays a few lines of at most a few hundred characters.
#[test]
fn a_huge_name_gets_a_short_error_at_once() {
    let src = format!(
        "chain default {{\n    accept if {};\n}}\n",
        "X".repeat(1_000_000)
    );
    let started = std::time::Instant::now();
    let text = all(&src);
    let took = started.elapsed();
    assert!(took < std::time::Duration::from_secs(1), "took {took:?}");
    assert!(
        text.starts_with("f:2:15: Invalid packet name (\"XXX"),
        "{text:.300}"
    );
    assert!(text.len() < 1_500, "{} bytes", text.len());
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 3, "{text}");
    assert!(lines[1].starts_with("    accept if XXX") && lines[1].ends_with('…'));
    assert!(lines[2].starts_with("              ^^^"), "{text}");
    // Near misses of ordinary length still get their suggestion.
    let near = all("chain default {\n    accept if HEARTBEET;\n}\n");
    assert!(near.contains("did you mean 'HEARTBEAT'?"), "{near}");
}

#[test]
fn record_file_names_must_fit_the_file_system() {
    // Names of up to 255 bytes, counting the suffix `-9999` a taken name gets.
    let name = format!("{}_%Y.tlog", "a".repeat(250));
    check(
        &format!("record {{ path /var/log/{name}; }}"),
        "1:24: the file names of this pattern take up to 265 bytes, more than the 255 a file name may have",
    );
    let fits = format!("{}_%Y.tlog", "a".repeat(225));
    assert!(config::load(&format!("record {{ path /var/log/{fits}; }}")).is_ok());
    // Every directive counted at its width (%Y: four digits), and the note says what to do.
    let text = all(&format!(
        "record {{\n    path {}.tlog;\n}}",
        "%Y".repeat(63)
    ));
    assert!(
        text.starts_with("f:2:10: the file names of this pattern take up to 262 bytes"),
        "{text}"
    );
    assert!(text.contains("note: counting the suffix -9999"), "{text}");
    // The list of recordings beside them is named after the pattern: it must fit too.
    check(
        &format!("record {{ path /r/{}.tlog; }}", "%%".repeat(118)),
        "1:18: the list of recordings of this pattern would be named with 256 bytes, more than the 255 a file name may have",
    );
    assert!(config::load(&format!("record {{ path /r/{}.tlog; }}", "%%".repeat(117))).is_ok());
}
