//! Per-rule counts do not depend on the verdict memo: a tiny, constantly colliding memo
//! and no memo at all count the same packets, bytes and decisions for every rule on
//! random (message, source, destination, signed) keys.

use mavtables::address::Address;
use mavtables::filter::Filter;
use proptest::prelude::*;

const CONF: &str = "
default_action accept;
chain default {
    reject if HEARTBEAT;
    reject if unsigned COMMAND_LONG;
    call a with priority 4 if from 1.0/8;
    goto b if to 2.0/8;
    accept with priority -2 if PING;
}
chain a {
    accept with priority 9 if to 3.3;
    reject if ATTITUDE;
}
chain b {
    accept with priority 6 if signed from 1.0/8;
    accept if PING from 1.1;
    reject if to 2.7;
}
";

proptest! {
    #[test]
    fn memoized_counts_equal_walked_counts(
        keys in prop::collection::vec(
            (prop::sample::select(vec![0u32, 4, 30, 24, 76]), 0u8..4, 0u8..8, 0u8..4, 0u8..8, any::<bool>(), 1usize..300),
            1..300,
        )
    ) {
        let config = mavtables::config::load(CONF).expect("config").config;
        let mut memo = Filter::with_cache_slots(&config, 4);
        let mut walk = Filter::with_cache_slots(&config, 0);
        for (id, ss, sc, ds, dc, signed, len) in keys.iter().copied() {
            let (src, dest) = (Address::new(ss, sc), Address::new(ds, dc));
            memo.check_len(id, src, dest, signed, len);
            walk.check_len(id, src, dest, signed, len);
        }
        let (m, w) = (memo.counts(), walk.counts());
        prop_assert_eq!(&m, &w);
        // Every evaluation was decided by exactly one rule or the default action.
        let decided: u64 = m.rules.iter().map(|r| r.decided).sum::<u64>() + m.default_packets;
        prop_assert_eq!(decided, keys.len() as u64);
    }
}

#[test]
fn a_call_that_falls_through_counts_as_matched_not_decided() {
    let config = mavtables::config::load(CONF).expect("config").config;
    let mut f = Filter::new(&config);
    // PING from 1.1 to 4.4: `call a` matches (a decides nothing), then `accept if PING`.
    for _ in 0..3 {
        f.check_len(4, Address::new(1, 1), Address::new(4, 4), false, 20);
    }
    let c = f.counts();
    let row = |i: usize| (c.rules[i].packets, c.rules[i].bytes, c.rules[i].decided);
    assert_eq!(row(2), (3, 60, 0)); // call a
    assert_eq!(row(4), (3, 60, 3)); // accept with priority -2 if PING
    assert_eq!(row(5), (0, 0, 0)); // a: accept with priority 9 if to 3.3 (not 4.4)
    assert_eq!(row(6), (0, 0, 0)); // a: reject if ATTITUDE
    assert_eq!(c.default_packets, 0);
}
