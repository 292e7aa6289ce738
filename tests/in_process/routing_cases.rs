//! Every routing case of the original (broadcast, system broadcast, targeted, component
//! fallback, loop prevention, priorities), on the routing core with an injected clock.

use crate::routing;

use routing::Net;

/// One serial link and two UDP remotes, everything accepted except HEARTBEAT.
const OPEN: &str = "
serial { device ./ttyS0; }
udp { port 14500; }
chain default {
    reject if HEARTBEAT;
    accept;
}
";

fn three_links(conf: &str) -> Net {
    let mut net = Net::new(conf);
    net.heartbeat("./ttyS0", "1.1");
    net.heartbeat("10.0.0.1:1", "2.1");
    net.heartbeat("10.0.0.2:2", "3.1");
    net.take_log();
    net
}

#[test]
fn never_echoed_to_the_source_link() {
    let mut net = three_links(OPEN);
    net.send("10.0.0.1:1", "ATTITUDE", "2.1", None);
    assert_eq!(net.drain("10.0.0.1:1"), Vec::<String>::new());
    assert_eq!(net.drain("./ttyS0"), ["ATTITUDE (#30) from 2.1 (v2.0)"]);
    assert_eq!(net.drain("10.0.0.2:2"), ["ATTITUDE (#30) from 2.1 (v2.0)"]);
    // No log line at all for the source link.
    assert_eq!(
        net.take_log(),
        [
            "received ATTITUDE (#30) from 2.1 (v2.0) source 10.0.0.1:1",
            "accepted ATTITUDE (#30) from 2.1 (v2.0) source 10.0.0.1:1 dest ./ttyS0",
            "accepted ATTITUDE (#30) from 2.1 (v2.0) source 10.0.0.1:1 dest 10.0.0.2:2",
        ]
    );
}

#[test]
fn loop_prevention_is_by_address_not_by_link() {
    // Two remotes that both host 2.1: packets from one never reach the other.
    let mut net = three_links(OPEN);
    net.heartbeat("10.0.0.2:2", "2.1");
    net.take_log();
    net.send("10.0.0.1:1", "ATTITUDE", "2.1", None);
    assert!(net.drain("10.0.0.2:2").is_empty());
    assert_eq!(net.drain("./ttyS0").len(), 1);
    assert_eq!(
        net.take_log().len(),
        2,
        "received + accepted for ttyS0 only"
    );
}

#[test]
fn broadcast_without_target_and_to_0_0() {
    let mut net = three_links(OPEN);
    net.send("./ttyS0", "PING", "1.1", Some("0.0"));
    net.send("./ttyS0", "ATTITUDE", "1.1", None);
    for l in ["10.0.0.1:1", "10.0.0.2:2"] {
        assert_eq!(
            net.drain(l),
            [
                "PING (#4) from 1.1 to 0.0 (v2.0)",
                "ATTITUDE (#30) from 1.1 (v2.0)"
            ]
        );
    }
}

#[test]
fn broadcast_filters_every_address_and_takes_the_max_priority() {
    let conf = "
serial { device ./ttyS0; }
chain default {
    accept with priority 2 if ATTITUDE to 1.1;
    accept with priority 7 if ATTITUDE to 1.2;
    reject if ATTITUDE to 1.3;
    accept with priority -5 if GPS_RAW_INT to 1.3;
}
";
    let mut net = Net::new(conf);
    for a in ["1.1", "1.2", "1.3"] {
        net.heartbeat("./ttyS0", a);
    }
    net.heartbeat("h:1", "9.9");
    net.take_log();
    net.send("h:1", "ATTITUDE", "9.9", None);
    net.send("h:1", "GPS_RAW_INT", "9.9", None);
    net.send("h:1", "ATTITUDE", "9.9", None);
    // Priority 7 (from 1.2) beats -5: both ATTITUDEs go before GPS_RAW_INT.
    assert_eq!(
        net.drain("./ttyS0"),
        [
            "ATTITUDE (#30) from 9.9 (v2.0)",
            "ATTITUDE (#30) from 9.9 (v2.0)",
            "GPS_RAW_INT (#24) from 9.9 (v2.0)"
        ]
    );
    let mut net = Net::new(conf);
    net.heartbeat("./ttyS0", "1.3");
    net.heartbeat("h:1", "9.9");
    net.take_log();
    net.send("h:1", "ATTITUDE", "9.9", None);
    assert!(net.drain("./ttyS0").is_empty());
    assert_eq!(
        net.take_log()[1],
        "rejected ATTITUDE (#30) from 9.9 (v2.0) source h:1 dest ./ttyS0"
    );
}

#[test]
fn broadcast_over_an_empty_pool_is_rejected_not_silent() {
    let mut net = Net::new(OPEN);
    net.send("10.0.0.1:1", "PING", "2.1", Some("0.0"));
    assert_eq!(
        net.take_log(),
        [
            "new component 2.1 on 10.0.0.1:1",
            "received PING (#4) from 2.1 to 0.0 (v2.0) source 10.0.0.1:1",
            "rejected PING (#4) from 2.1 to 0.0 (v2.0) source 10.0.0.1:1 dest ./ttyS0",
        ]
    );
}

#[test]
fn system_broadcast_goes_to_the_systems_addresses_only() {
    let conf = "
serial { device ./ttyS0; }
chain default {
    accept if SET_MODE to 5.2;
    reject;
}
";
    let mut net = Net::new(conf);
    net.heartbeat("./ttyS0", "5.1");
    net.heartbeat("./ttyS0", "5.2");
    net.heartbeat("./ttyS0", "6.2");
    net.heartbeat("a:1", "6.1");
    net.take_log();
    // SET_MODE has only a target_system: `to 5.0`, a system broadcast.
    net.send("a:1", "SET_MODE", "6.1", Some("5.0"));
    assert_eq!(
        net.drain("./ttyS0"),
        ["SET_MODE (#11) from 6.1 to 5.0 (v2.0)"]
    );
    // Filtered only for 5.1 and 5.2: with only 6.2 accepted it would be rejected.
    let conf_6 = "serial { device ./ttyS0; }\nchain default { accept if SET_MODE to 6.2; }";
    let mut net = Net::new(conf_6);
    net.heartbeat("./ttyS0", "5.1");
    net.heartbeat("./ttyS0", "6.2");
    net.heartbeat("a:1", "6.1");
    net.take_log();
    net.send("a:1", "SET_MODE", "6.1", Some("5.0"));
    assert!(net.drain("./ttyS0").is_empty());
    assert_eq!(
        net.take_log(),
        [
            "received SET_MODE (#11) from 6.1 to 5.0 (v2.0) source a:1",
            "rejected SET_MODE (#11) from 6.1 to 5.0 (v2.0) source a:1 dest ./ttyS0",
        ]
    );
}

#[test]
fn system_broadcast_to_an_unknown_system_is_silent() {
    let mut net = three_links(OPEN);
    net.send("./ttyS0", "SET_MODE", "1.1", Some("42.0"));
    assert_eq!(
        net.take_log(),
        ["received SET_MODE (#11) from 1.1 to 42.0 (v2.0) source ./ttyS0"]
    );
}

#[test]
fn targeted_goes_only_where_the_target_lives() {
    let mut net = three_links(OPEN);
    net.send("./ttyS0", "PING", "1.1", Some("3.1"));
    assert!(net.drain("10.0.0.1:1").is_empty());
    assert_eq!(
        net.drain("10.0.0.2:2"),
        ["PING (#4) from 1.1 to 3.1 (v2.0)"]
    );
    assert_eq!(
        net.take_log(),
        [
            "received PING (#4) from 1.1 to 3.1 (v2.0) source ./ttyS0",
            "accepted PING (#4) from 1.1 to 3.1 (v2.0) source ./ttyS0 dest 10.0.0.2:2",
        ]
    );
}

#[test]
fn targeted_at_an_unknown_system_is_silent() {
    let mut net = three_links(OPEN);
    net.send("./ttyS0", "PING", "1.1", Some("77.1"));
    assert_eq!(net.take_log().len(), 1, "only `received`");
    // System 0 with a component (0.7) is targeted too: nobody has system 0.
    net.send("./ttyS0", "PING", "1.1", Some("0.7"));
    assert_eq!(net.take_log().len(), 1, "only `received`");
}

#[test]
fn targeted_rejection_is_logged() {
    let conf = "serial { device ./ttyS0; }\nchain default { reject if PING; accept; }";
    let mut net = Net::new(conf);
    net.heartbeat("./ttyS0", "1.1");
    net.heartbeat("u:1", "2.1");
    net.take_log();
    net.send("u:1", "PING", "2.1", Some("1.1"));
    assert_eq!(
        net.take_log()[1],
        "rejected PING (#4) from 2.1 to 1.1 (v2.0) source u:1 dest ./ttyS0"
    );
}

#[test]
fn component_fallback_filters_with_the_original_destination() {
    let conf = "
serial { device ./ttyS0; }
chain default {
    accept if PARAM_REQUEST_LIST to 1.5;
    reject;
}
";
    let mut net = Net::new(conf);
    net.heartbeat("./ttyS0", "1.1");
    net.heartbeat("u:1", "255.190");
    net.take_log();
    // 1.5 never spoke, but system 1 lives behind ttyS0, and the filter sees `to 1.5`.
    net.send("u:1", "PARAM_REQUEST_LIST", "255.190", Some("1.5"));
    assert_eq!(
        net.drain("./ttyS0"),
        ["PARAM_REQUEST_LIST (#21) from 255.190 to 1.5 (v2.0)"]
    );
    // The same packet to 1.6 is filtered with 1.6 and rejected (once).
    net.take_log();
    net.send("u:1", "PARAM_REQUEST_LIST", "255.190", Some("1.6"));
    assert_eq!(
        net.take_log(),
        [
            "received PARAM_REQUEST_LIST (#21) from 255.190 to 1.6 (v2.0) source u:1",
            "rejected PARAM_REQUEST_LIST (#21) from 255.190 to 1.6 (v2.0) source u:1 dest ./ttyS0",
        ]
    );
}

#[test]
fn learning_happens_before_filtering_even_for_rejected_packets() {
    let mut net = Net::new(OPEN);
    net.heartbeat("u:1", "7.7");
    assert_eq!(
        net.take_log(),
        [
            "new component 7.7 on u:1",
            "received HEARTBEAT (#0) from 7.7 (v2.0) source u:1",
            "rejected HEARTBEAT (#0) from 7.7 (v2.0) source u:1 dest ./ttyS0",
        ]
    );
    net.send("./ttyS0", "PING", "1.1", Some("7.7"));
    assert_eq!(net.drain("u:1"), ["PING (#4) from 1.1 to 7.7 (v2.0)"]);
}

#[test]
fn links_are_offered_in_creation_order() {
    let mut net =
        Net::new("serial { device /dev/b; }\nserial { device /dev/a; }\ndefault_action accept;");
    net.heartbeat("9.9.9.9:9", "9.1");
    net.heartbeat("1.1.1.1:1", "1.1");
    net.take_log();
    net.send("./src:0", "ATTITUDE", "5.5", None);
    let dests: Vec<String> = net
        .take_log()
        .iter()
        .filter_map(|l| l.split(" dest ").nth(1).map(str::to_string))
        .collect();
    assert_eq!(dests, ["/dev/b", "/dev/a", "9.9.9.9:9", "1.1.1.1:1"]);
}

#[test]
fn v1_frames_route_and_print_as_v1() {
    let mut net = three_links(OPEN);
    net.recv("./ttyS0", &routing::frame_v1("PING", "1.1", Some("2.1")));
    assert_eq!(
        net.drain("10.0.0.1:1"),
        ["PING (#4) from 1.1 to 2.1 (v1.0)"]
    );
}

#[test]
fn the_same_bytes_are_queued_for_every_link() {
    let mut net = three_links(OPEN);
    let f = routing::frame("ATTITUDE", "1.1", None);
    net.recv("./ttyS0", &f);
    let a = net.router.pop(net.links["10.0.0.1:1"]).expect("queued");
    let b = net.router.pop(net.links["10.0.0.2:2"]).expect("queued");
    assert_eq!(&a[..], &f[..]);
    assert!(
        std::sync::Arc::ptr_eq(&a, &b),
        "one buffer shared, not copied"
    );
}

#[test]
fn event_level_limits_what_is_produced() {
    let mut net = three_links(OPEN);
    net.router.set_event_level(1);
    net.send("./ttyS0", "ATTITUDE", "1.2", None);
    assert_eq!(net.take_log(), ["new component 1.2 on ./ttyS0"]);
    net.router.set_event_level(0);
    net.send("./ttyS0", "ATTITUDE", "1.3", None);
    assert!(net.take_log().is_empty());
    assert_eq!(net.drain("10.0.0.1:1").len(), 2, "routing is unaffected");
}

#[test]
fn unknown_source_link_is_ignored() {
    let mut net = three_links(OPEN);
    let f = routing::frame("ATTITUDE", "1.1", None);
    let frame = mavtables::wire::Frame::parse_exact(&f).expect("frame");
    let mut out = mavtables::routing::Output::default();
    net.router
        .receive(mavtables::routing::LinkId(999), &frame, net.now, &mut out);
    assert!(out.events.is_empty() && out.queued.is_empty());
}
