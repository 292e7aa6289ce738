//! The packet filter: chains of `accept` / `reject` / `call` / `goto` rules evaluated for
//! every (packet, destination address) pair, exactly as the original mavtables did
//! (`docs/configuration.md` describes them for users).
//!
//! The result of the filter depends only on the packet's message id, its source address,
//! the destination address being filtered for and whether the packet arrived signed, so
//! [`Filter`] memoizes it in a small bounded cache ([`cache`]): a router that evaluates
//! the filter once per candidate address per link pays the rule walk (`eval`) only for
//! the first packet of each (message id, source, destination, signed) key, however many
//! rules the configuration has.
//!
//! ```
//! use mavtables::address::Address;
//! use mavtables::filter::{Filter, Verdict};
//!
//! let config = mavtables::config::load("chain default { accept with priority 3 if PING; }")
//!     .unwrap()
//!     .config;
//! let mut filter = Filter::new(&config);
//! let (src, dest) = (Address::new(1, 1), Address::new(2, 1));
//! assert_eq!(filter.check(4, src, dest, false), Verdict::Accept(3)); // PING
//! assert_eq!(filter.check(0, src, dest, false), Verdict::Reject); // HEARTBEAT: default_action
//! ```

#[doc(hidden)]
pub mod cache;
pub(crate) mod eval;
pub(crate) mod trace;

use crate::address::Address;
use crate::config::Config;

pub use cache::{CacheStats, VerdictCache};
pub use eval::Evaluator;
pub use trace::{FilterCounts, RuleCounts, Traces};

/// The filter's answer for one (packet, destination address) pair.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Verdict {
    /// Forward with this priority (larger = more important; unset priorities are 0).
    Accept(i32),
    /// Do not forward to this address.
    Reject,
}

impl Verdict {
    /// The priority if accepted.
    pub fn priority(self) -> Option<i32> {
        match self {
            Verdict::Accept(p) => Some(p),
            Verdict::Reject => None,
        }
    }
}

/// The `with rate` that holds back a packet a rule accepted, as [`Filter::check_capped`]
/// gives it: the rank of the rule's interval among the configuration's distinct ones
/// (1 the shortest, so the loosest; 0 no cap at all), and where the deciding rule can be
/// found (for its `rate_limited` count). Ranks order as intervals do, so the looser of
/// two caps is the one of smaller rank, and no cap is looser than any.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Cap {
    rank: u32,
    /// The trace number of the walk that decided, or [`DIRECT`] and the deciding rule's
    /// flat number when that trace was not interned.
    origin: u32,
}

/// Set in [`Cap::origin`] when it holds a rule number, not a trace number.
const DIRECT: u32 = 1 << 31;

impl Cap {
    /// No cap: the packet passes as it is.
    pub const NONE: Cap = Cap { rank: 0, origin: 0 };

    /// Whether there is a cap.
    #[inline]
    pub fn is_capped(self) -> bool {
        self.rank != 0
    }

    /// The looser of `self` and `other`: no cap beats any, else the shorter interval;
    /// `self` on a tie.
    #[inline]
    pub fn looser(self, other: Cap) -> Cap {
        if other.rank < self.rank { other } else { self }
    }
}

/// The configuration's chains and default action, with a memo of past verdicts and
/// per-rule hit counts.
#[derive(Debug, Clone)]
pub struct Filter {
    evaluator: Evaluator,
    cache: VerdictCache,
    traces: Traces,
    /// The cap rank of each rule by flat number (0: no rate); empty when no rule has a
    /// rate.
    ranks: Box<[u32]>,
    /// The interval of each rank in nanoseconds, shortest first (index 0, no cap, holds 0).
    intervals: Box<[u64]>,
}

/// The cap ranks of `config`'s rules by flat number and the interval of each rank (see
/// [`Cap`]); both empty when no rule has a rate.
fn ranks_of(config: &Config) -> (Box<[u32]>, Box<[u64]>) {
    let rules = config.chains.iter().flat_map(|c| &c.rules);
    let nanos = |r: &crate::config::Rule| {
        r.rate
            .map(|r| u64::try_from(r.interval().as_nanos()).unwrap_or(u64::MAX))
    };
    let mut intervals: Vec<u64> = rules.clone().filter_map(nanos).collect();
    if intervals.is_empty() {
        return (Box::new([]), Box::new([]));
    }
    intervals.push(0);
    intervals.sort_unstable();
    intervals.dedup();
    let rank = |n: u64| {
        let at = intervals.binary_search(&n).unwrap_or(0);
        u32::try_from(at).unwrap_or(u32::MAX)
    };
    let ranks = rules.map(|r| nanos(r).map_or(0, rank)).collect();
    (ranks, intervals.into_boxed_slice())
}

impl Filter {
    /// Builds the filter of `config` with a cache of [`cache::DEFAULT_SLOTS`] entries.
    pub fn new(config: &Config) -> Self {
        Filter::with_cache_slots(config, cache::DEFAULT_SLOTS)
    }

    /// Builds the filter of `config` with a cache of (at least) `slots` entries; 0 turns
    /// memoization off.
    pub fn with_cache_slots(config: &Config, slots: usize) -> Self {
        let (ranks, intervals) = ranks_of(config);
        Filter {
            evaluator: Evaluator::new(config),
            cache: VerdictCache::new(slots),
            traces: Traces::default(),
            ranks,
            intervals,
        }
    }

    /// The verdict for a packet with `message_id` from `source`, filtered for `dest`;
    /// `signed` tells whether it arrived with an accepted signature (for `if signed` and
    /// `if unsigned` rules). Counted as an evaluation of no bytes (see
    /// [`Filter::check_len`]).
    #[inline]
    pub fn check(
        &mut self,
        message_id: u32,
        source: Address,
        dest: Address,
        signed: bool,
    ) -> Verdict {
        self.check_len(message_id, source, dest, signed, 0)
    }

    /// As [`Filter::check`], for a frame of `len` bytes: the evaluation is counted for
    /// every rule whose condition matched and for the rule (or default action) that
    /// decided, whether the verdict came from the memo or from a walk.
    #[inline]
    pub fn check_len(
        &mut self,
        message_id: u32,
        source: Address,
        dest: Address,
        signed: bool,
        len: usize,
    ) -> Verdict {
        self.check_capped(message_id, source, dest, signed, len).0
    }

    /// As [`Filter::check_len`], with the [`Cap`] of the rule that accepted
    /// ([`Cap::NONE`] for a reject, an accept by a rule without `with rate`, or by the
    /// default action). The cap comes from the rule that decided, so a memoized verdict
    /// gives it too (from the same memo slot); holding packets to it is the caller's (it
    /// is state that changes with every packet).
    #[inline]
    pub fn check_capped(
        &mut self,
        message_id: u32,
        source: Address,
        dest: Address,
        signed: bool,
        len: usize,
    ) -> (Verdict, Cap) {
        if let Some(m) = self.cache.get_traced(message_id, source, dest, signed) {
            self.traces.hit(m.trace, len);
            let cap = Cap {
                rank: m.rank,
                origin: m.trace,
            };
            return (m.verdict, cap);
        }
        let verdict = self.evaluator.evaluate(message_id, source, dest, signed);
        let (matched, decider) = self.evaluator.trace();
        let rank = match (verdict, decider) {
            (Verdict::Accept(_), Some(rule)) => self.ranks.get(rule as usize).copied().unwrap_or(0),
            _ => 0,
        };
        let origin = match self.traces.intern(matched, decider) {
            Some(trace) => {
                self.traces.hit(trace, len);
                let memo = cache::Memo {
                    verdict,
                    trace,
                    rank,
                };
                self.cache
                    .insert_traced(message_id, source, dest, signed, memo);
                trace
            }
            // The trace table is full: counted directly, and walked again next time.
            None => {
                self.traces.hit_direct(matched, decider, len);
                DIRECT | decider.unwrap_or(0)
            }
        };
        (verdict, Cap { rank, origin })
    }

    /// The interval of `cap` in nanoseconds (0 for no cap).
    #[inline]
    pub fn interval_nanos(&self, cap: Cap) -> u64 {
        self.intervals.get(cap.rank as usize).copied().unwrap_or(0)
    }

    /// Whether `other` caps at the same set of rates (a stream's schedule means the
    /// same under both).
    pub fn same_rates(&self, other: &Filter) -> bool {
        self.intervals == other.intervals
    }

    /// Whether any rule has a `with rate`.
    pub fn has_caps(&self) -> bool {
        !self.ranks.is_empty()
    }

    /// Counts one packet that the rule of `cap` accepted for a link but its rate held
    /// back.
    pub fn count_rate_limited(&mut self, cap: Cap) {
        let rule = if cap.origin & DIRECT != 0 {
            Some(cap.origin & !DIRECT)
        } else {
            self.traces.decider(cap.origin)
        };
        if let Some(rule) = rule {
            self.traces.rate_limited(rule);
        }
    }

    /// Per-rule counts (by flat rule number: chains in configuration order, their rules
    /// in order) and the default action's.
    pub fn counts(&self) -> FilterCounts {
        self.traces.rule_counts(self.evaluator.rule_count())
    }

    /// Goes on from `counts` (by this filter's flat rule numbers): what a reload carried
    /// over from the filter this one replaces is part of [`Filter::counts`] from now on.
    pub(crate) fn carry_counts(&mut self, counts: &FilterCounts) {
        self.traces.carry(counts);
    }

    /// Hits and misses of the memo so far.
    pub fn cache_stats(&self) -> CacheStats {
        self.cache.stats()
    }
}
