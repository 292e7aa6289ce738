//! The semantic model: defaults, resolved names, subnets, joined chains, warnings.

use mavtables::address::{Address, Subnet};
use mavtables::config::{
    Action, ChainId, Condition, Config, DefaultAction, Interface, PeerLimits, QueueBounds,
    SerialInterface, UdpInterface, load,
};
use std::net::{IpAddr, Ipv4Addr};

fn config(src: &str) -> Config {
    match load(src) {
        Ok(l) => l.config,
        Err(e) => panic!("{}", mavtables::config::render_errors("t", src, &e)),
    }
}

fn heartbeat() -> u32 {
    mavtables::dialect::by_name("HEARTBEAT")
        .map(|m| m.id)
        .expect("HEARTBEAT")
}

#[test]
fn defaults() {
    let c = config("udp {}\nserial { device /dev/ttyUSB0; }\nchain default {}");
    assert_eq!(c.default_action, DefaultAction::Reject);
    assert_eq!(
        c.interfaces,
        [
            Interface::Udp(UdpInterface {
                port: 14500,
                address: None,
                max_bitrate: None,
                connect: None,
                peers: PeerLimits {
                    max_peers: 128,
                    allow: vec![]
                },
                signing: None,
            }),
            Interface::Serial(SerialInterface {
                device: "/dev/ttyUSB0".into(),
                baudrate: 9600,
                flow_control: false,
                preload: vec![],
                max_bitrate: None,
                signing: None,
            }),
        ]
    );
}

#[test]
fn values_last_wins_and_preloads_accumulate() {
    let c = config(
        "default_action reject; default_action accept;\n\
         udp { port 1; port 14550; address 127.0.0.1; max_bitrate 0; }\n\
         udp { max_bitrate 8388608; }\n\
         serial { device /dev/serial/by-id/usb-A:1-if00; baudrate 921600; flow_control yes; preload 1.1; preload 62.34; }\n\
         chain default { accept; }",
    );
    assert_eq!(c.default_action, DefaultAction::Accept);
    assert_eq!(
        c.interfaces[0],
        Interface::Udp(UdpInterface {
            port: 14550,
            address: Some(IpAddr::V4(Ipv4Addr::new(127, 0, 0, 1))),
            max_bitrate: None,
            ..UdpInterface::default()
        })
    );
    assert!(matches!(&c.interfaces[1], Interface::Udp(u) if u.max_bitrate == Some(8_388_608)));
    assert_eq!(
        c.interfaces[2],
        Interface::Serial(SerialInterface {
            device: "/dev/serial/by-id/usb-A:1-if00".into(),
            baudrate: 921_600,
            flow_control: true,
            preload: vec![Address::new(1, 1), Address::new(62, 34)],
            max_bitrate: None,
            signing: None,
        })
    );
}

#[test]
fn chains_resolve_before_definition_and_repeated_blocks_join() {
    let c = config(
        "chain default { call later with priority 4; goto later if to 1.0/8; }\n\
         chain later { reject; }\n\
         chain default { accept; }\n\
         chain later { accept with priority -3; }",
    );
    let default = c.chain(c.default_chain);
    let later = c.chain_by_name("later").expect("later");
    assert_eq!(default.name, "default");
    assert_eq!(default.rules.len(), 3);
    assert_eq!(default.rules[0].action, Action::Call(later));
    assert_eq!(default.rules[0].priority, Some(4));
    assert_eq!(default.rules[1].action, Action::Goto(later));
    assert_eq!(
        default.rules[1].condition.dest,
        Subnet::with_prefix(Address::new(1, 0), 8)
    );
    assert_eq!(default.rules[2].action, Action::Accept);
    let rules: Vec<_> = c
        .chain(later)
        .rules
        .iter()
        .map(|r| (r.action, r.priority))
        .collect();
    assert_eq!(rules, [(Action::Reject, None), (Action::Accept, Some(-3))]);
}

#[test]
fn conditions_resolve_names_and_subnets() {
    let c = config(
        "chain default {\n\
           accept if HEARTBEAT from 1.2 to 3.4:255.0;\n\
           accept if from 10.255/9 to 9.128\\1;\n\
           reject with priority 7;\n\
           accept;\n\
         }",
    );
    let r = &c.chain(c.default_chain).rules;
    assert_eq!(
        r[0].condition,
        Condition {
            signed: None,
            message_id: Some(heartbeat()),
            source: Some(Subnet::exact(Address::new(1, 2))),
            dest: Some(Subnet::new(Address::new(3, 4), Address::new(255, 0))),
        }
    );
    assert_eq!(r[1].condition.source.map(|s| s.mask), Some(0xFF80));
    assert_eq!(r[1].condition.dest.map(|s| s.mask), Some(0x0080));
    // A priority on a reject rule has no effect and is dropped.
    assert_eq!(r[2].priority, None);
    assert_eq!(r[3].condition, Condition::default());
    assert!(
        r[3].condition
            .matches(99, Address::new(1, 1), Address::new(2, 2), false)
    );
    assert!(
        r[0].condition
            .matches(heartbeat(), Address::new(1, 2), Address::new(3, 9), false)
    );
    assert!(
        !r[0]
            .condition
            .matches(heartbeat(), Address::new(1, 2), Address::new(4, 4), false)
    );
}

#[test]
fn missing_default_chain_is_a_warning_with_an_empty_default() {
    let loaded = load("udp {}").expect("valid");
    assert_eq!(
        loaded.warnings,
        ["no 'default' chain is defined, so every packet gets the default action (reject)"]
    );
    let c = loaded.config;
    assert_eq!(c.chain(c.default_chain).name, "default");
    assert!(c.chain(c.default_chain).rules.is_empty());
    assert_eq!(c.default_chain, ChainId(0));
    assert!(load("chain default {}").expect("valid").warnings.is_empty());
}

#[test]
fn acyclic_graphs_with_shared_targets_are_fine() {
    // A diamond is not a cycle.
    config(
        "chain default { call a; call b; }\nchain a { call c; }\nchain b { goto c; }\nchain c { accept; }",
    );
    // A very long chain of chains does not overflow the stack.
    let mut src = String::from("chain default { call c0; }\n");
    for i in 0..20_000 {
        src += &format!("chain c{i} {{ call c{}; }}\n", i + 1);
    }
    src += "chain c20000 { accept; }\n";
    assert_eq!(config(&src).chains.len(), 20_002);
}

#[test]
fn real_message_names_resolve_to_their_ids() {
    let c = config(
        "chain default {\n\
           reject if ENCAPSULATED_DATA;\n\
           accept if PING;\n\
           accept if GPS_STATUS;\n\
           accept if HEARTBEAT;\n\
           accept if MISSION_REQUEST_LIST;\n\
         }",
    );
    let ids: Vec<_> = c
        .chain(c.default_chain)
        .rules
        .iter()
        .map(|r| r.condition.message_id)
        .collect();
    assert_eq!(ids, [Some(131), Some(4), Some(25), Some(0), Some(43)]);
}

#[test]
fn unknown_names_get_close_real_suggestions() {
    let src = "chain default { accept if GPS_STATU; reject if PNG; }";
    let text = match load(src) {
        Ok(_) => panic!("should fail"),
        Err(e) => mavtables::config::render_errors("f", src, &e),
    };
    assert!(
        text.contains("f:1:27: Invalid packet name (\"GPS_STATU\").\n"),
        "{text}"
    );
    assert!(text.contains("'GPS_STATUS'"), "{text}");
    assert!(
        text.contains("f:1:48: Invalid packet name (\"PNG\").\n"),
        "{text}"
    );
    assert!(text.contains("'PING'"), "{text}");
}

#[test]
fn queue_bounds() {
    // No block, or an empty one: the routing core's defaults.
    for src in ["chain default {}", "queue {}\nchain default {}"] {
        assert_eq!(config(src).queue, QueueBounds::default());
    }
    let c = config("queue {\n    link_bytes 4194304;\n    total_bytes 33554432;\n}");
    assert_eq!(
        c.queue,
        QueueBounds {
            link_bytes: Some(4_194_304),
            total_bytes: Some(33_554_432)
        }
    );
    // Each statement alone; the smallest and largest values; the last of a repeat counts.
    let c = config("queue { link_bytes 0312; }");
    assert_eq!(c.queue.link_bytes, Some(312));
    assert_eq!(c.queue.total_bytes, None);
    let c = config("queue { total_bytes 400; total_bytes 1000; }");
    assert_eq!(c.queue.total_bytes, Some(1000));
    assert_eq!(c.queue.link_bytes, None);
    #[cfg(target_pointer_width = "64")]
    assert_eq!(
        config("queue { total_bytes 1099511627776; }")
            .queue
            .total_bytes,
        Some(1 << 40)
    );
    // Equal bounds are allowed.
    let c = config("queue { link_bytes 5000; total_bytes 5000; }");
    assert_eq!(c.queue.total_bytes, Some(5000));
}
