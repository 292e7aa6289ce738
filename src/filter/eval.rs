//! Walks the chains of a [`Config`] for one (message id, source, destination, signed)
//! key.
//!
//! The original mavtables' semantics: rules run in order and the first that decides
//! wins; a rule whose condition fails continues. `call X` returns X's result as-is, so
//! an undecided X falls through to the caller's next rule; `goto X` turns an undecided X
//! into "default", which ends evaluation with the default action. A priority on `call`/`goto` is attached only
//! to an accept that has none yet (innermost explicit priority wins). Unset priority is 0.
//!
//! `SETUP_SIGNING` carries a signing key in the clear: an `accept` rule takes it only if
//! its condition names it (`accept if SETUP_SIGNING ...`), and the default action never
//! accepts it; every other rule treats it as any packet.
//!
//! The walk uses an explicit stack, never recursion, and gives up with
//! [`Verdict::Reject`] when the stack is deeper than the number of chains: an acyclic
//! model can never get there (each chain appears at most once on a call path), so only a
//! cyclic model, which the config layer already refuses, is affected.

use super::Verdict;
use crate::address::Address;
use crate::config::{Action, Chain, Condition, Config, DefaultAction};
use crate::dialect::SETUP_SIGNING_ID;

/// What a chain (or rule) evaluates to before the default action is applied.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Outcome {
    Accept(Option<i32>),
    Reject,
    Continue,
    Default,
}

/// How a chain on the stack was entered.
#[derive(Debug, Clone, Copy)]
enum Entry {
    Start,
    Call(Option<i32>),
    Goto(Option<i32>),
}

/// One chain being evaluated: where to resume in it and how it was entered.
#[derive(Debug, Clone, Copy)]
struct CallFrame {
    chain: usize,
    next_rule: usize,
    entry: Entry,
}

/// True when `action` with `condition` may not take a packet of `message_id`: an
/// `accept` that does not name `SETUP_SIGNING` does not take it.
#[inline]
fn withheld(message_id: u32, action: Action, condition: &Condition) -> bool {
    message_id == SETUP_SIGNING_ID
        && action == Action::Accept
        && condition.message_id != Some(SETUP_SIGNING_ID)
}

/// The chains of a configuration, ready to evaluate (no memo; see [`super::Filter`]).
#[derive(Debug, Clone)]
pub struct Evaluator {
    chains: Vec<Chain>,
    /// The flat number of each chain's first rule (rules numbered across all chains in
    /// chain order), for [`Evaluator::trace`].
    first_rule: Vec<u32>,
    start: usize,
    default_action: DefaultAction,
    stack: Vec<CallFrame>,
    /// The rules whose condition matched in the last walk, in walk order (flat numbers).
    matched: Vec<u32>,
    /// The accept or reject rule that decided the last walk, if one did.
    decider: Option<u32>,
}

impl Evaluator {
    /// Takes the chains, start chain and default action of `config`.
    pub fn new(config: &Config) -> Self {
        let mut first_rule = Vec::with_capacity(config.chains.len());
        let mut n = 0u32;
        for c in &config.chains {
            first_rule.push(n);
            n = n.saturating_add(u32::try_from(c.rules.len()).unwrap_or(u32::MAX));
        }
        Evaluator {
            chains: config.chains.clone(),
            first_rule,
            start: config.default_chain.0,
            default_action: config.default_action,
            stack: Vec::with_capacity(config.chains.len() + 1),
            matched: Vec::new(),
            decider: None,
        }
    }

    /// The flat number of rule `rule` of chain `chain` (rules numbered across all chains
    /// in chain order, as [`Evaluator::trace`] gives them).
    pub fn rule_number(&self, chain: usize, rule: usize) -> Option<u32> {
        let first = *self.first_rule.get(chain)?;
        let len = self.chains.get(chain)?.rules.len();
        (rule < len).then(|| first.saturating_add(u32::try_from(rule).unwrap_or(u32::MAX)))
    }

    /// How many rules all chains hold together.
    pub(crate) fn rule_count(&self) -> usize {
        self.chains.iter().map(|c| c.rules.len()).sum()
    }

    /// What the last [`Evaluator::evaluate`] walked: the flat numbers of the rules whose
    /// condition matched, in walk order (`call`/`goto` rules included), and the accept or
    /// reject rule that decided (`None`: the default action decided).
    pub fn trace(&self) -> (&[u32], Option<u32>) {
        (&self.matched, self.decider)
    }

    /// The verdict for a packet with `message_id` from `source`, filtered for `dest`;
    /// `signed` tells whether it arrived with an accepted signature.
    pub fn evaluate(
        &mut self,
        message_id: u32,
        source: Address,
        dest: Address,
        signed: bool,
    ) -> Verdict {
        match self.walk(message_id, source, dest, signed) {
            Outcome::Accept(p) => Verdict::Accept(p.unwrap_or(0)),
            Outcome::Reject => Verdict::Reject,
            Outcome::Continue | Outcome::Default => match self.default_action {
                DefaultAction::Accept if message_id != SETUP_SIGNING_ID => Verdict::Accept(0),
                DefaultAction::Accept | DefaultAction::Reject => Verdict::Reject,
            },
        }
    }

    fn walk(&mut self, message_id: u32, source: Address, dest: Address, signed: bool) -> Outcome {
        let depth_limit = self.chains.len().max(1);
        self.stack.clear();
        self.matched.clear();
        self.decider = None;
        self.stack.push(CallFrame {
            chain: self.start,
            next_rule: 0,
            entry: Entry::Start,
        });
        loop {
            let Some(top) = self.stack.last_mut() else {
                return Outcome::Continue;
            };
            let rule = self
                .chains
                .get(top.chain)
                .and_then(|c| c.rules.get(top.next_rule));
            // The outcome with which the chain at the top of the stack finishes.
            let mut result = match rule {
                None => Outcome::Continue,
                Some(rule) => {
                    top.next_rule += 1;
                    if !rule.condition.matches(message_id, source, dest, signed)
                        || withheld(message_id, rule.action, &rule.condition)
                    {
                        continue;
                    }
                    let number = self
                        .first_rule
                        .get(top.chain)
                        .map_or(u32::MAX, |f| f.saturating_add((top.next_rule - 1) as u32));
                    self.matched.push(number);
                    match rule.action {
                        Action::Accept => {
                            self.decider = Some(number);
                            Outcome::Accept(rule.priority)
                        }
                        Action::Reject => {
                            self.decider = Some(number);
                            Outcome::Reject
                        }
                        Action::Call(_) | Action::Goto(_) if self.stack.len() >= depth_limit => {
                            // Only a cyclic model gets this deep: refuse the packet.
                            return Outcome::Reject;
                        }
                        Action::Call(c) => {
                            self.push(c.0, Entry::Call(rule.priority));
                            continue;
                        }
                        Action::Goto(c) => {
                            self.push(c.0, Entry::Goto(rule.priority));
                            continue;
                        }
                    }
                }
            };
            // Hand the result to the rule that entered the chain, and on up while decided.
            loop {
                let Some(frame) = self.stack.pop() else {
                    return result;
                };
                result = match (frame.entry, result) {
                    (Entry::Start, r) => return r,
                    (Entry::Goto(_), Outcome::Continue) => Outcome::Default,
                    (Entry::Call(p) | Entry::Goto(p), Outcome::Accept(None)) => Outcome::Accept(p),
                    (_, r) => r,
                };
                if result == Outcome::Continue {
                    break; // an undecided `call`: the caller goes on with its next rule
                }
            }
        }
    }

    fn push(&mut self, chain: usize, entry: Entry) {
        self.stack.push(CallFrame {
            chain,
            next_rule: 0,
            entry,
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::{ChainId, Condition, QueueBounds, Rule};

    const HEARTBEAT: u32 = 0;
    const PING: u32 = 4;

    fn eval(src: &str, id: u32, from: (u8, u8), to: (u8, u8)) -> Verdict {
        let config = crate::config::load(src).expect("test config loads").config;
        Evaluator::new(&config).evaluate(
            id,
            Address::new(from.0, from.1),
            Address::new(to.0, to.1),
            false,
        )
    }

    #[test]
    fn empty_config_uses_default_action() {
        let reject = "udp { port 14500; }";
        assert_eq!(eval(reject, PING, (1, 1), (2, 2)), Verdict::Reject);
        let accept = "default_action accept;";
        assert_eq!(eval(accept, PING, (1, 1), (2, 2)), Verdict::Accept(0));
    }

    #[test]
    fn first_match_wins() {
        let src =
            "chain default { reject if PING; accept with priority 2; accept with priority 9; }";
        assert_eq!(eval(src, PING, (1, 1), (2, 2)), Verdict::Reject);
        assert_eq!(eval(src, HEARTBEAT, (1, 1), (2, 2)), Verdict::Accept(2));
    }

    #[test]
    fn conditions_are_anded_and_to_is_the_filtered_destination() {
        let src = "chain default { accept if PING from 1.0/8 to 2.2; }";
        assert_eq!(eval(src, PING, (1, 7), (2, 2)), Verdict::Accept(0));
        assert_eq!(eval(src, PING, (3, 7), (2, 2)), Verdict::Reject);
        assert_eq!(eval(src, PING, (1, 7), (2, 3)), Verdict::Reject);
        assert_eq!(eval(src, HEARTBEAT, (1, 7), (2, 2)), Verdict::Reject);
    }

    #[test]
    fn call_falls_through_to_the_next_rule() {
        let src = "chain default { call c; accept with priority 5; }\nchain c { reject if PING; }";
        assert_eq!(eval(src, PING, (1, 1), (2, 2)), Verdict::Reject);
        assert_eq!(eval(src, HEARTBEAT, (1, 1), (2, 2)), Verdict::Accept(5));
    }

    #[test]
    fn goto_falls_to_default_action() {
        let src = "default_action accept;\nchain default { goto c with priority 5; reject; }\nchain c { reject if PING; }";
        // Undecided goto: default action (accept, priority 0: the 5 is not applied).
        assert_eq!(eval(src, HEARTBEAT, (1, 1), (2, 2)), Verdict::Accept(0));
        assert_eq!(eval(src, PING, (1, 1), (2, 2)), Verdict::Reject);
        let src = "chain default { goto c; accept; }\nchain c { accept if PING; }";
        assert_eq!(eval(src, HEARTBEAT, (1, 1), (2, 2)), Verdict::Reject);
    }

    #[test]
    fn goto_default_inside_a_call_ends_everything() {
        let src = "chain default { call a; accept with priority 1; }\nchain a { goto b; }\nchain b { reject if PING; }";
        assert_eq!(eval(src, HEARTBEAT, (1, 1), (2, 2)), Verdict::Reject);
        assert_eq!(eval(src, PING, (1, 1), (2, 2)), Verdict::Reject);
    }

    #[test]
    fn innermost_priority_wins() {
        let src = "chain default { call a with priority 3; }\nchain a { accept with priority 10 if PING; accept; }";
        assert_eq!(eval(src, PING, (1, 1), (2, 2)), Verdict::Accept(10));
        assert_eq!(eval(src, HEARTBEAT, (1, 1), (2, 2)), Verdict::Accept(3));
        let src = "chain default { goto a with priority 3; }\nchain a { accept with priority 0; }";
        assert_eq!(eval(src, PING, (1, 1), (2, 2)), Verdict::Accept(0));
        let src = "chain default { call a with priority 1; }\nchain a { call b with priority 2; }\nchain b { accept; }";
        assert_eq!(eval(src, PING, (1, 1), (2, 2)), Verdict::Accept(2));
    }

    #[test]
    fn priority_on_reject_is_ignored() {
        let src = "default_action accept;\nchain default { reject with priority 9 if PING; }";
        assert_eq!(eval(src, PING, (1, 1), (2, 2)), Verdict::Reject);
        assert_eq!(eval(src, HEARTBEAT, (1, 1), (2, 2)), Verdict::Accept(0));
    }

    #[test]
    fn negative_priorities() {
        let src = "chain default { accept with priority -4; }";
        assert_eq!(eval(src, PING, (1, 1), (2, 2)), Verdict::Accept(-4));
    }

    fn rule(action: Action) -> Rule {
        Rule {
            action,
            priority: None,
            condition: Condition::default(),
            rate: None,
        }
    }

    #[test]
    fn a_cyclic_model_is_refused_not_recursed() {
        // The config layer refuses cycles; a hand-built cyclic model must still terminate.
        let config = Config {
            default_action: DefaultAction::Accept,
            interfaces: vec![],
            chains: vec![
                Chain {
                    name: "default".into(),
                    rules: vec![rule(Action::Call(ChainId(1)))],
                },
                Chain {
                    name: "a".into(),
                    rules: vec![rule(Action::Call(ChainId(2)))],
                },
                Chain {
                    name: "b".into(),
                    rules: vec![rule(Action::Goto(ChainId(1)))],
                },
            ],
            default_chain: ChainId(0),
            queue: QueueBounds::default(),
            ..Config::accept_all(vec![])
        };
        let mut e = Evaluator::new(&config);
        assert_eq!(
            e.evaluate(PING, Address::new(1, 1), Address::new(2, 2), false),
            Verdict::Reject
        );
        let self_loop = Config {
            chains: vec![Chain {
                name: "default".into(),
                rules: vec![rule(Action::Goto(ChainId(0)))],
            }],
            ..config
        };
        let mut e = Evaluator::new(&self_loop);
        assert_eq!(
            e.evaluate(PING, Address::new(1, 1), Address::new(2, 2), false),
            Verdict::Reject
        );
    }

    #[test]
    fn dangling_chain_ids_do_not_panic() {
        let config = Config {
            default_action: DefaultAction::Accept,
            interfaces: vec![],
            chains: vec![Chain {
                name: "default".into(),
                rules: vec![rule(Action::Call(ChainId(7)))],
            }],
            default_chain: ChainId(3),
            queue: QueueBounds::default(),
            ..Config::accept_all(vec![])
        };
        let mut e = Evaluator::new(&config);
        assert_eq!(
            e.evaluate(PING, Address::new(1, 1), Address::new(2, 2), false),
            Verdict::Accept(0)
        );
    }

    #[test]
    fn deep_acyclic_call_chains_are_evaluated() {
        let mut src = String::from("chain default { call c0; }\n");
        for i in 0..200 {
            src.push_str(&format!("chain c{i} {{ call c{}; }}\n", i + 1));
        }
        src.push_str("chain c200 { accept with priority 7; }\n");
        assert_eq!(eval(&src, PING, (1, 1), (2, 2)), Verdict::Accept(7));
    }
}
