//! `--ast` golden tests: the original mavtables' tree format, byte for byte.

use mavtables::config::{parse, print_ast, print_tree};

fn tree(src: &str) -> String {
    match parse(src) {
        Ok(ast) => print_tree(&ast),
        Err(d) => panic!("{}", d.render("t", src)),
    }
}

#[test]
fn golden_file_with_every_form() {
    let path = "tests/data/config/everything.conf";
    let src = std::fs::read_to_string(path).expect("fixture");
    let want = std::fs::read_to_string("tests/data/config/everything.ast").expect("golden");
    let ast = parse(&src).expect("fixture parses");
    assert_eq!(print_ast(&ast, path), want);
}

#[test]
fn golden_file_with_queue_blocks() {
    let path = "tests/data/config/queue.conf";
    let src = std::fs::read_to_string(path).expect("fixture");
    let want = std::fs::read_to_string("tests/data/config/queue.ast").expect("golden");
    let ast = parse(&src).expect("fixture parses");
    assert_eq!(print_ast(&ast, path), want);
}

#[test]
fn golden_file_with_network_statements() {
    let path = "tests/data/config/network.conf";
    let src = std::fs::read_to_string(path).expect("fixture");
    let want = std::fs::read_to_string("tests/data/config/network.ast").expect("golden");
    let ast = parse(&src).expect("fixture parses");
    assert_eq!(print_ast(&ast, path), want);
    // The fixture is a valid configuration too.
    if let Err(e) = mavtables::config::load(&src) {
        panic!("{}", mavtables::config::render_errors(path, &src, &e));
    }
}

#[test]
fn network_statements_print_raw_like_udp_settings() {
    assert_eq!(
        tree("tcp\n{\n    connect\n        [::1]:5760;\n}"),
        ":001:  tcp\n:004:  |  connect [::1]:5760\n"
    );
    for src in ["tcp {}", "tcp\n{\n}"] {
        assert_eq!(tree(src), ":001:  tcp\n");
    }
    assert_eq!(
        tree("udp { max_peers 010; allow ::/0; allow 10.0.0.0/8; address fd00::7; }"),
        ":001:  udp\n:001:  |  max_peers 010\n:001:  |  allow ::/0\n:001:  |  allow 10.0.0.0/8\n:001:  |  address fd00::7\n"
    );
    assert_eq!(
        tree("serial { device a; max_bitrate 57600; }"),
        ":001:  serial\n:001:  |  device a\n:001:  |  max_bitrate 57600\n"
    );
    // --ast checks syntax only: a bad octet or port prints raw.
    assert_eq!(
        tree("udp { connect 300.1.1.1:0; }"),
        ":001:  udp\n:001:  |  connect 300.1.1.1:0\n"
    );
}

#[test]
fn queue_block_prints_like_udp() {
    for src in ["queue {}", "queue\n{\n}"] {
        assert_eq!(tree(src), ":001:  queue\n");
    }
    assert_eq!(
        tree("queue {\n    link_bytes 4096;\n    total_bytes\n  08192;\n}"),
        ":001:  queue\n:002:  |  link_bytes 4096\n:004:  |  total_bytes 08192\n"
    );
}

#[test]
fn global_statements_and_empty_blocks() {
    assert_eq!(
        tree("default_action accept;"),
        ":001:  default_action\n:001:  |  accept\n"
    );
    assert_eq!(
        tree("default_action reject;"),
        ":001:  default_action\n:001:  |  reject\n"
    );
    for src in ["udp {}", "udp {\n}", "udp\n{\n}"] {
        assert_eq!(tree(src), ":001:  udp\n");
    }
    for src in ["serial {}", "serial {\n}", "serial\n{\n}"] {
        assert_eq!(tree(src), ":001:  serial\n");
    }
    assert_eq!(tree("chain default {}"), ":001:  chain default\n");
}

#[test]
fn block_settings_keep_raw_text() {
    assert_eq!(
        tree("udp {\n    port 014500;\n    address 127.0.0.1;\n    max_bitrate 8388608;\n}"),
        ":001:  udp\n:002:  |  port 014500\n:003:  |  address 127.0.0.1\n:004:  |  max_bitrate 8388608\n"
    );
    assert_eq!(
        tree(
            "serial {\n    device COM1;\n    baudrate 115200;\n    flow_control yes;\n    preload 62.34;\n}"
        ),
        ":001:  serial\n:002:  |  device COM1\n:003:  |  baudrate 115200\n:004:  |  flow_control yes\n:005:  |  preload 62.34\n"
    );
}

#[test]
fn every_rule_shape() {
    let actions = [
        ("accept", "accept"),
        ("reject", "reject"),
        ("call x1", "call x1"),
        ("goto x1", "goto x1"),
    ];
    let priorities = [
        ("", None),
        (" with priority 99", Some("99")),
        (" with priority -1", Some("-1")),
    ];
    let conditions: [(&str, &[&str]); 8] = [
        ("", &[]),
        (" if PING", &["packet_type PING"]),
        (" if PING from 127.1", &["packet_type PING", "source 127.1"]),
        (" if PING to 192.0", &["packet_type PING", "dest 192.0"]),
        (
            " if PING from 127.1 to 192.0",
            &["packet_type PING", "source 127.1", "dest 192.0"],
        ),
        (" if from 127.1/9", &["source 127.1/9"]),
        (" if to 192.0\\4", &["dest 192.0\\4"]),
        (
            " if from 255.0:128.240 to 0.0",
            &["source 255.0:128.240", "dest 0.0"],
        ),
    ];
    for (action, node) in actions {
        for (prio, prio_node) in priorities {
            for (cond, cond_nodes) in conditions {
                let src = format!("chain default {{\n    {action}{prio}{cond};\n}}");
                let mut want = format!(":001:  chain default\n:002:  |  {node}\n");
                if let Some(p) = prio_node {
                    want += &format!(":002:  |  |  priority {p}\n");
                }
                if !cond_nodes.is_empty() {
                    want += ":002:  |  |  condition\n";
                    for n in cond_nodes {
                        want += &format!(":002:  |  |  |  {n}\n");
                    }
                }
                assert_eq!(tree(&src), want, "source: {src}");
            }
        }
    }
}

#[test]
fn line_numbers_are_where_each_node_text_starts() {
    // The chain name, the call target, the priority number and the `if` keyword.
    let src = "chain\n  main\n{\n  call\n  other\n  with\n  priority\n  5\n  if\n  PING\n  from\n  1.1;\n}";
    assert_eq!(
        tree(src),
        ":002:  chain main\n:005:  |  call other\n:008:  |  |  priority 5\n:009:  |  |  condition\n\
         :010:  |  |  |  packet_type PING\n:012:  |  |  |  source 1.1\n"
    );
    let far = format!("{}udp {{}}", "\n".repeat(1200));
    assert_eq!(tree(&far), ":1201:  udp\n");
}

#[test]
fn punctuation_needs_no_spaces_and_comments_go_anywhere() {
    assert_eq!(
        tree("udp{port 14500;}chain default{accept if from 1.1;}"),
        ":001:  udp\n:001:  |  port 14500\n:001:  chain default\n:001:  |  accept\n:001:  |  |  condition\n:001:  |  |  |  source 1.1\n"
    );
    assert_eq!(
        tree("chain # c\n default # c\n { # c\n accept # c\n ; # c\n } # c"),
        ":002:  chain default\n:004:  |  accept\n"
    );
}

#[test]
fn ast_checks_syntax_only() {
    // Out-of-range values and unknown names are semantic errors: --ast still prints them.
    assert_eq!(
        tree("udp { port 99999; }\nchain default { call nowhere if NOT_A_MSG; }"),
        ":001:  udp\n:001:  |  port 99999\n:002:  chain default\n:002:  |  call nowhere\n:002:  |  |  condition\n:002:  |  |  |  packet_type NOT_A_MSG\n"
    );
}

#[test]
fn zenoh_statements_print_raw() {
    assert_eq!(
        tree(
            "zenoh {\n    mode peer;\n    listen tcp/127.0.0.1:7448;\n    connect tcp/[::1]:7447;\n    prefix fleet/alpha;\n    receive all;\n    signing_key k.key;\n    allow_unsigned yes;\n}"
        ),
        ":001:  zenoh\n:002:  |  mode peer\n:003:  |  listen tcp/127.0.0.1:7448\n:004:  |  connect tcp/[::1]:7447\n:005:  |  prefix fleet/alpha\n:006:  |  receive all\n:007:  |  signing_key k.key\n:008:  |  allow_unsigned yes\n"
    );
    assert_eq!(tree("zenoh {}"), ":001:  zenoh\n");
}
