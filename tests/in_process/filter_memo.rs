//! The verdict memo never changes an answer nor a count: a tiny, constantly colliding
//! memo agrees with a direct rule walk on random (message, source, destination, signed)
//! keys, and counts the same packets, bytes and decisions for every rule.

use mavtables::address::Address;
use mavtables::filter::{Evaluator, Filter, Verdict};
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
    fn memo_agrees_with_the_rule_walk(
        triples in prop::collection::vec(
            (prop::sample::select(vec![0u32, 4, 30, 24, 76]), 0u8..4, 0u8..8, 0u8..4, 0u8..8, any::<bool>()),
            1..200,
        )
    ) {
        let config = mavtables::config::load(CONF).expect("config").config;
        let mut memo = Filter::with_cache_slots(&config, 4);
        let mut walk = Evaluator::new(&config);
        for (id, ss, sc, ds, dc, signed) in triples {
            let (src, dest) = (Address::new(ss, sc), Address::new(ds, dc));
            prop_assert_eq!(memo.check(id, src, dest, signed), walk.evaluate(id, src, dest, signed));
        }
    }
}

#[test]
fn repeated_packets_are_answered_from_the_memo() {
    let config = mavtables::config::load(CONF).expect("config").config;
    let mut f = Filter::new(&config);
    for _ in 0..100 {
        for d in 0..5 {
            f.check(30, Address::new(1, 1), Address::new(3, d), false);
        }
    }
    let s = f.cache_stats();
    assert_eq!((s.hits, s.misses), (495, 5));
}

#[test]
fn signed_and_unsigned_verdicts_of_one_triple_are_memoized_apart() {
    let config =
        mavtables::config::load("chain default { accept with priority 5 if signed; reject; }")
            .expect("config")
            .config;
    let mut f = Filter::new(&config);
    let (src, dest) = (Address::new(1, 1), Address::new(2, 1));
    for _ in 0..3 {
        assert_eq!(f.check(76, src, dest, true), Verdict::Accept(5));
        assert_eq!(f.check(76, src, dest, false), Verdict::Reject);
    }
    let s = f.cache_stats();
    assert_eq!((s.hits, s.misses), (4, 2));
}

#[test]
fn rules_on_the_signed_bit() {
    let config = mavtables::config::load(CONF).expect("config").config;
    let mut f = Filter::new(&config);
    // COMMAND_LONG (76) from 5.5 to 9.9: rejected unsigned, accepted (default) signed.
    let (src, dest) = (Address::new(5, 5), Address::new(9, 9));
    assert_eq!(f.check(76, src, dest, false), Verdict::Reject);
    assert_eq!(f.check(76, src, dest, true), Verdict::Accept(0));
    // GPS_RAW_INT (24) from 1.3 to 2.1 passes chain a undecided and goes to chain b:
    // signed packets from system 1 get priority 6 there; unsigned ones fall through the
    // goto to the default action (priority 0).
    let (src, dest) = (Address::new(1, 3), Address::new(2, 1));
    assert_eq!(f.check(24, src, dest, true), Verdict::Accept(6));
    assert_eq!(f.check(24, src, dest, false), Verdict::Accept(0));
}

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
