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
use std::time::Duration;

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

/// The `with rate` of the rule that accepted a packet: the rule's flat number (for its
/// `rate_limited` count) and the least time between two packets of one stream.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Cap {
    /// The deciding rule's flat number (chains in order, their rules in order).
    pub rule: u32,
    /// The interval of its rate.
    pub interval: Duration,
}

/// The configuration's chains and default action, with a memo of past verdicts and
/// per-rule hit counts.
#[derive(Debug, Clone)]
pub struct Filter {
    evaluator: Evaluator,
    cache: VerdictCache,
    traces: Traces,
    /// The rate interval of each rule by flat number; empty when no rule has a rate.
    caps: Box<[Option<Duration>]>,
    /// The cap of each interned trace (by trace number: that of its deciding rule), so
    /// that a memoized verdict finds its cap with one load.
    trace_caps: Vec<Option<Cap>>,
}

/// The rate intervals of `config`'s rules by flat number; empty when none has a rate.
fn caps_of(config: &Config) -> Box<[Option<Duration>]> {
    let rules = config.chains.iter().flat_map(|c| &c.rules);
    if rules.clone().all(|r| r.rate.is_none()) {
        return Box::new([]);
    }
    rules.map(|r| r.rate.map(|r| r.interval())).collect()
}

impl Filter {
    /// Builds the filter of `config` with a cache of [`cache::DEFAULT_SLOTS`] entries.
    pub fn new(config: &Config) -> Self {
        Filter::with_cache_slots(config, cache::DEFAULT_SLOTS)
    }

    /// Builds the filter of `config` with a cache of (at least) `slots` entries; 0 turns
    /// memoization off.
    pub fn with_cache_slots(config: &Config, slots: usize) -> Self {
        Filter {
            evaluator: Evaluator::new(config),
            cache: VerdictCache::new(slots),
            traces: Traces::default(),
            caps: caps_of(config),
            trace_caps: Vec::new(),
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

    /// As [`Filter::check_len`], with the [`Cap`] of the rule that accepted (`None` for a
    /// reject, an accept by a rule without `with rate`, or by the default action). The
    /// cap comes from the rule that decided, so a memoized verdict gives it too; holding
    /// packets to it is the caller's (it is state that changes with every packet).
    #[inline]
    pub fn check_capped(
        &mut self,
        message_id: u32,
        source: Address,
        dest: Address,
        signed: bool,
        len: usize,
    ) -> (Verdict, Option<Cap>) {
        if let Some((v, trace)) = self.cache.get_traced(message_id, source, dest, signed) {
            self.traces.hit(trace, len);
            let cap = self.trace_caps.get(trace as usize).copied().flatten();
            return (v, cap);
        }
        let v = self.evaluator.evaluate(message_id, source, dest, signed);
        let (matched, decider) = self.evaluator.trace();
        match self.traces.intern(matched, decider) {
            Some(trace) => {
                self.traces.hit(trace, len);
                self.cache
                    .insert_traced(message_id, source, dest, signed, v, trace);
                if !self.caps.is_empty() && trace as usize == self.trace_caps.len() {
                    self.trace_caps.push(self.cap(decider));
                }
            }
            // The trace table is full: counted directly, and walked again next time.
            None => self.traces.hit_direct(matched, decider, len),
        }
        let cap = match v {
            Verdict::Accept(_) => self.cap(decider),
            Verdict::Reject => None,
        };
        (v, cap)
    }

    /// The cap of rule `decider` (only `accept` rules have one).
    #[inline]
    fn cap(&self, decider: Option<u32>) -> Option<Cap> {
        let rule = decider?;
        let interval = (*self.caps.get(rule as usize)?)?;
        Some(Cap { rule, interval })
    }

    /// Whether any rule has a `with rate`.
    pub fn has_caps(&self) -> bool {
        !self.caps.is_empty()
    }

    /// Counts one packet that rule `rule` accepted for a link but its rate held back.
    pub fn count_rate_limited(&mut self, rule: u32) {
        self.traces.rate_limited(rule);
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
