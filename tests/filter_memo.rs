//! The verdict memo never changes an answer: a tiny, constantly colliding memo agrees
//! with a direct rule walk on random (message, source, destination) triples.

use mavtables::address::Address;
use mavtables::filter::{Evaluator, Filter};
use proptest::prelude::*;

const CONF: &str = "
default_action accept;
chain default {
    reject if HEARTBEAT;
    call a with priority 4 if from 1.0/8;
    goto b if to 2.0/8;
    accept with priority -2 if PING;
}
chain a {
    accept with priority 9 if to 3.3;
    reject if ATTITUDE;
}
chain b {
    accept if PING from 1.1;
    reject if to 2.7;
}
";

proptest! {
    #[test]
    fn memo_agrees_with_the_rule_walk(
        triples in prop::collection::vec(
            (prop::sample::select(vec![0u32, 4, 30, 24]), 0u8..4, 0u8..8, 0u8..4, 0u8..8),
            1..200,
        )
    ) {
        let config = mavtables::config::load(CONF).expect("config").config;
        let mut memo = Filter::with_cache_slots(&config, 4);
        let mut walk = Evaluator::new(&config);
        for (id, ss, sc, ds, dc) in triples {
            let (src, dest) = (Address::new(ss, sc), Address::new(ds, dc));
            prop_assert_eq!(memo.check(id, src, dest), walk.evaluate(id, src, dest));
        }
    }
}

#[test]
fn repeated_packets_are_answered_from_the_memo() {
    let config = mavtables::config::load(CONF).expect("config").config;
    let mut f = Filter::new(&config);
    for _ in 0..100 {
        for d in 0..5 {
            f.check(30, Address::new(1, 1), Address::new(3, d));
        }
    }
    let s = f.cache_stats();
    assert_eq!((s.hits, s.misses), (495, 5));
}
