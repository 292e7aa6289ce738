//! Property test of the routing core's queues under any mix of traffic, sending and
//! expiry: the shared byte count always equals what the queues hold, never passes the
//! shared capacity, and every packet offered is either queued, sent or counted as a drop.

use crate::routing;

use proptest::prelude::*;
use routing::{Net, frame};

/// One step of a run.
#[derive(Debug, Clone)]
enum Step {
    /// Link `link` sends message `kind` from component `from` to `to` (None: broadcast).
    Send {
        link: usize,
        kind: usize,
        from: u8,
        to: Option<u8>,
    },
    /// Link `link` sends up to `n` queued packets.
    Drain { link: usize, n: usize },
    /// Time passes (seconds), then housekeeping (expiry removes silent UDP links).
    Wait(u64),
}

const LINKS: [&str; 4] = ["u:1", "u:2", "u:3", "./ttyS0"];
/// Messages of different lengths (ENCAPSULATED_DATA is the largest).
const KINDS: [&str; 3] = ["ATTITUDE", "ENCAPSULATED_DATA", "FILE_TRANSFER_PROTOCOL"];

fn step() -> impl Strategy<Value = Step> {
    prop_oneof![
        6 => (0..LINKS.len(), 0..KINDS.len(), 1u8..5, prop::option::of(1u8..5)).prop_map(
            |(link, kind, from, to)| Step::Send { link, kind, from, to }
        ),
        2 => (0..LINKS.len(), 0usize..20).prop_map(|(link, n)| Step::Drain { link, n }),
        1 => (0u64..200).prop_map(Step::Wait),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]
    #[test]
    fn shared_queue_accounting_holds(
        steps in prop::collection::vec(step(), 1..300),
        per_link in 1usize..12,
        shared in 1usize..30,
    ) {
        let options = routing::queue_options(per_link * 300, shared * 300);
        let mut net = Net::with_options(
            "serial { device ./ttyS0; }\nchain default {\n    accept with priority 2 if ATTITUDE;\n    accept with priority -1 if to 3.3;\n    accept;\n}\n",
            options,
        );
        let (mut offered, mut sent, mut gone) = (0u64, 0u64, 0u64);
        let mut clock = 0;
        for s in steps {
            match s {
                Step::Send { link, kind, from, to } => {
                    // FILE_TRANSFER_PROTOCOL needs a target; the others have none.
                    let to = (KINDS[kind] == "FILE_TRANSFER_PROTOCOL").then(|| to.unwrap_or(1));
                    let f = frame(KINDS[kind], &format!("{from}.{from}"), to.map(|t| format!("{t}.{t}")).as_deref());
                    net.recv(LINKS[link], &f);
                    // Counted from the log, apart from the queues: one "accepted" event
                    // per packet handed to a link's queue.
                    offered += net.take_log().iter().filter(|l| l.starts_with("accepted ")).count() as u64;
                }
                Step::Drain { link, n } => {
                    if let Some(&id) = net.links.get(LINKS[link]) {
                        for _ in 0..n {
                            if net.router.pop(id).is_none() {
                                break;
                            }
                            sent += 1;
                        }
                    }
                }
                Step::Wait(secs) => {
                    let held: usize = net.router.links().map(|l| l.queue().len()).sum();
                    clock += secs;
                    net.at(clock);
                    net.tick();
                    let left: usize = net.router.links().map(|l| l.queue().len()).sum();
                    gone += (held - left) as u64;
                }
            }
            let bytes: usize = net.router.links().map(|l| l.queue().bytes()).sum();
            prop_assert_eq!(bytes, net.router.queued_bytes());
            prop_assert!(bytes <= shared * 300, "{} > {}", bytes, shared * 300);
            let held: usize = net.router.links().map(|l| l.queue().len()).sum();
            prop_assert_eq!(offered, held as u64 + sent + gone + net.drops);
        }
    }
}
