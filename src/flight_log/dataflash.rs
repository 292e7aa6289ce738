//! ArduPilot's dataflash stream: numbered 200-byte blocks, each acknowledged; a missing
//! block is asked for again (NACK) until it comes or is given up, and blocks go to the
//! file in order. Pure: blocks and time in, statuses to send and ordered bytes out.

use std::collections::BTreeMap;
use std::time::Duration;

use super::messages::DATAFLASH_BLOCK;
use crate::time::Timestamp;

/// Most blocks held while an earlier one is missing (200 KB): far beyond the blocks
/// ArduPilot keeps for resending, so a block still missing then will not come.
pub(crate) const WINDOW: u32 = 1024;
/// A missing block is asked for again after this long.
pub(crate) const ASK_AGAIN: Duration = Duration::from_millis(200);
/// A missing block is given up after this many NACKs.
pub(crate) const MAX_ASKS: u8 = 10;
/// Seqnos from here on are not blocks of a log: 2^31 blocks would be 400 GB, and the
/// status values ArduPilot reserves for start and stop (2147483645, 2147483646) lie
/// just below 2^31. Such a block is ignored (neither acknowledged nor written), so the
/// order's arithmetic never comes near `u32::MAX`.
pub(crate) const MAX_SEQNO: u32 = 0x7FFF_FFF0;
/// At most this many NACKs are sent for one received block (a long gap is asked for
/// over the following turns).
const NACKS_PER_BLOCK: usize = 32;

/// A block not received yet.
#[derive(Debug, Clone, Copy)]
struct Missing {
    asked: u8,
    /// When it was last asked for (`None`: not yet).
    at: Option<Timestamp>,
}

/// What one input asks for: statuses to send (seqno, ACK or not) and bytes in order.
#[derive(Debug, Default)]
pub(crate) struct Acts {
    /// `(seqno, true)` for an ACK, `(seqno, false)` for a NACK.
    pub statuses: Vec<(u32, bool)>,
    /// Blocks now in order, back to back.
    pub bytes: Vec<u8>,
    /// How many blocks `bytes` holds.
    pub blocks: u32,
    /// Blocks that came after being NACKed.
    pub resent: u64,
    /// Blocks given up.
    pub lost: u64,
    /// Blocks received again after they were in order.
    pub duplicates: u64,
}

/// What a block means for the log.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Verdict {
    /// Part of this log.
    Taken,
    /// Far before this log's blocks: the autopilot started a new log (it rebooted).
    NewLog,
}

/// The order of one log's blocks.
#[derive(Debug, Default)]
pub(crate) struct Dataflash {
    /// The next seqno the file takes.
    next: u32,
    /// The highest seqno received (valid once `seen`).
    highest: u32,
    seen: bool,
    /// Blocks received after a missing one, by seqno.
    held: BTreeMap<u32, Box<[u8; DATAFLASH_BLOCK]>>,
    /// Blocks below `highest` not received yet.
    missing: BTreeMap<u32, Missing>,
}

impl Dataflash {
    /// A log whose first block is 0 (ArduPilot numbers each log from 0).
    pub(crate) fn new() -> Self {
        Dataflash::default()
    }

    /// The next seqno the file takes.
    pub(crate) fn next(&self) -> u32 {
        self.next
    }

    /// The highest seqno received, once one was.
    pub(crate) fn highest(&self) -> Option<u32> {
        self.seen.then_some(self.highest)
    }

    /// Blocks held back behind a missing one.
    #[cfg(test)]
    pub(crate) fn held(&self) -> usize {
        self.held.len()
    }

    /// Takes block `seqno` with `data`, received at `now`.
    pub(crate) fn block(
        &mut self,
        seqno: u32,
        data: &[u8; DATAFLASH_BLOCK],
        now: Timestamp,
        acts: &mut Acts,
    ) -> Verdict {
        if seqno >= MAX_SEQNO {
            return Verdict::Taken;
        }
        if seqno < self.next {
            if self.next - seqno > WINDOW {
                return Verdict::NewLog;
            }
            // Our ACK was lost: say it again.
            acts.duplicates += 1;
            acts.statuses.push((seqno, true));
            return Verdict::Taken;
        }
        if !self.seen && seqno > WINDOW {
            // Joined a stream already under way: it starts here.
            self.next = seqno;
        } else if self.seen && seqno - self.next > WINDOW {
            // Far ahead: what lies between will not come; keep what came.
            let keep = std::mem::take(&mut self.held);
            for (s, block) in keep {
                self.give_up_before(s, acts);
                self.deliver(&block, acts);
            }
            acts.lost += self.missing.len() as u64;
            self.missing.clear();
            acts.lost += u64::from(seqno.saturating_sub(self.highest.saturating_add(1)));
            self.next = seqno;
            self.highest = seqno - 1;
        }
        acts.statuses.push((seqno, true));
        if self.missing.remove(&seqno).is_some() {
            acts.resent += 1;
        }
        if seqno > self.highest || !self.seen {
            let from = if self.seen {
                self.highest + 1
            } else {
                self.next
            };
            for s in from..seqno {
                self.missing.insert(s, Missing { asked: 0, at: None });
            }
            self.highest = seqno;
            self.seen = true;
        }
        if seqno == self.next {
            self.deliver(data, acts);
            self.drain(acts);
        } else {
            match self.held.entry(seqno) {
                std::collections::btree_map::Entry::Vacant(v) => {
                    v.insert(Box::new(*data));
                }
                std::collections::btree_map::Entry::Occupied(_) => acts.duplicates += 1,
            }
        }
        // Asking may give up the block the file waits for: what that frees goes on.
        self.ask(now, NACKS_PER_BLOCK, acts);
        self.drain(acts);
        Verdict::Taken
    }

    /// Ends the log: every missing block is given up, and the blocks held behind the
    /// gaps go to the file in order (they were acknowledged: the autopilot will not send
    /// them again).
    pub(crate) fn finish(&mut self, acts: &mut Acts) {
        acts.lost += self.missing.len() as u64;
        self.missing.clear();
        self.drain(acts);
    }

    /// Asks again for the missing blocks due at `now`, gives up those asked for too
    /// often, and delivers what that frees.
    pub(crate) fn handle_timeout(&mut self, now: Timestamp, acts: &mut Acts) {
        self.ask(now, usize::MAX, acts);
        self.drain(acts);
    }

    /// When a missing block is next asked for, if one is missing.
    pub(crate) fn poll_timeout(&self) -> Option<Timestamp> {
        self.missing
            .values()
            .map(|m| m.at.map_or(Timestamp::ZERO, |t| t + ASK_AGAIN))
            .min()
    }

    /// NACKs up to `most` missing blocks due at `now` (never asked, or asked
    /// `ASK_AGAIN` ago); those asked `MAX_ASKS` times are given up.
    fn ask(&mut self, now: Timestamp, most: usize, acts: &mut Acts) {
        let mut sent = 0;
        let mut gone = Vec::new();
        for (&s, m) in self.missing.iter_mut() {
            if sent >= most {
                break;
            }
            if m.at.is_some_and(|t| now < t + ASK_AGAIN) {
                continue;
            }
            if m.asked >= MAX_ASKS {
                gone.push(s);
                continue;
            }
            m.asked += 1;
            m.at = Some(now);
            acts.statuses.push((s, false));
            sent += 1;
        }
        for s in gone {
            self.missing.remove(&s);
            acts.lost += 1;
        }
        if self.held.len() > WINDOW as usize {
            // Holding too much: the first gap will not be filled in time.
            if let Some((&s, _)) = self.held.iter().next() {
                self.give_up_before(s, acts);
            }
        }
    }

    /// Gives up every missing block before `seqno`.
    fn give_up_before(&mut self, seqno: u32, acts: &mut Acts) {
        let rest = self.missing.split_off(&seqno);
        acts.lost += self.missing.len() as u64;
        self.missing = rest;
        self.next = self.next.max(seqno);
    }

    /// Hands the blocks now in order to the file: held ones, skipping given-up ones.
    fn drain(&mut self, acts: &mut Acts) {
        loop {
            if let Some(block) = self.held.remove(&self.next) {
                self.deliver(&block, acts);
            } else if self.seen
                && self.next <= self.highest
                && !self.missing.contains_key(&self.next)
            {
                // Given up: the file goes on without it.
                self.next = self.next.saturating_add(1);
            } else {
                return;
            }
        }
    }

    fn deliver(&mut self, data: &[u8; DATAFLASH_BLOCK], acts: &mut Acts) {
        acts.bytes.extend_from_slice(data);
        acts.blocks += 1;
        self.next = self.next.saturating_add(1);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn data(n: u32) -> [u8; DATAFLASH_BLOCK] {
        [n as u8; DATAFLASH_BLOCK]
    }

    /// Found by the fuzzer: a block numbered near `u32::MAX` made `drain` overflow (in a
    /// release build it would have wrapped and walked four billion seqnos).
    #[test]
    fn seqnos_beyond_any_log_are_ignored() {
        let mut d = Dataflash::new();
        let mut acts = Acts::default();
        let t = Timestamp::ZERO;
        for s in [u32::MAX, u32::MAX - 1, MAX_SEQNO, 2_147_483_646] {
            assert_eq!(d.block(s, &data(1), t, &mut acts), Verdict::Taken);
        }
        assert!(acts.statuses.is_empty() && acts.bytes.is_empty());
        // A log still starts at 0 after them.
        d.block(0, &data(0), t, &mut acts);
        assert_eq!((acts.blocks, d.next()), (1, 1));
        // Joined late just below the limit: the order stops short of it.
        let mut late = Dataflash::new();
        let mut acts = Acts::default();
        late.block(MAX_SEQNO - 1, &data(2), t, &mut acts);
        late.handle_timeout(t, &mut acts);
        assert_eq!(acts.blocks, 1);
    }

    fn at(ms: u64) -> Timestamp {
        Timestamp::from_millis(ms)
    }

    #[test]
    fn in_order_blocks_are_acked_and_written() {
        let mut d = Dataflash::new();
        let mut acts = Acts::default();
        for s in 0..3 {
            d.block(s, &data(s), at(0), &mut acts);
        }
        assert_eq!(acts.statuses, [(0, true), (1, true), (2, true)]);
        assert_eq!(acts.blocks, 3);
        assert_eq!(acts.bytes.len(), 600);
    }

    #[test]
    fn a_gap_is_nacked_then_filled_in_order() {
        let mut d = Dataflash::new();
        let mut acts = Acts::default();
        d.block(0, &data(0), at(0), &mut acts);
        d.block(2, &data(2), at(1), &mut acts);
        assert_eq!(acts.statuses, [(0, true), (2, true), (1, false)]);
        assert_eq!(acts.blocks, 1);
        d.block(1, &data(1), at(2), &mut acts);
        assert_eq!(acts.blocks, 3);
        assert_eq!(acts.resent, 1);
        assert_eq!(&acts.bytes[200..400], &data(1));
        assert_eq!(&acts.bytes[400..600], &data(2));
        assert_eq!(d.poll_timeout(), None);
    }

    #[test]
    fn a_finished_log_writes_what_it_held_behind_its_gaps() {
        let mut d = Dataflash::new();
        let mut acts = Acts::default();
        for s in (0..3).chain(4..6).chain(8..10) {
            d.block(s, &data(s), at(0), &mut acts);
        }
        assert_eq!((acts.blocks, d.held()), (3, 4));
        let mut end = Acts::default();
        d.finish(&mut end);
        assert_eq!((end.blocks, end.lost, d.held()), (4, 3, 0));
        let want: Vec<u8> = [4, 5, 8, 9].iter().flat_map(|&s| data(s)).collect();
        assert_eq!(end.bytes, want);
        assert!(end.statuses.is_empty());
    }

    #[test]
    fn a_block_that_never_comes_is_given_up() {
        let mut d = Dataflash::new();
        let mut acts = Acts::default();
        d.block(0, &data(0), at(0), &mut acts);
        d.block(2, &data(2), at(0), &mut acts);
        let mut now = 0;
        while d.poll_timeout().is_some() {
            now += 200;
            d.handle_timeout(at(now), &mut acts);
            assert!(now < 10_000);
        }
        let nacks = acts.statuses.iter().filter(|(_, ack)| !ack).count();
        assert_eq!(nacks, usize::from(MAX_ASKS));
        assert_eq!((acts.lost, acts.blocks), (1, 2));
    }

    /// The block the file waits for is given up while another block is taken (its last
    /// ask ran out in that turn): the file goes on at once, with nothing left to wait for.
    #[test]
    fn a_block_given_up_while_another_comes_lets_the_file_go_on() {
        let mut d = Dataflash::new();
        let mut acts = Acts::default();
        d.block(0, &data(0), at(0), &mut acts);
        d.block(2, &data(2), at(0), &mut acts);
        for k in 1..u64::from(MAX_ASKS) {
            d.handle_timeout(at(200 * k), &mut acts);
        }
        assert_eq!(acts.blocks, 1, "block 1 still awaited");
        d.block(3, &data(3), at(2000), &mut acts);
        assert_eq!((acts.blocks, acts.lost), (3, 1));
        assert_eq!(d.poll_timeout(), None);
        assert_eq!(d.next(), 4);
    }

    #[test]
    fn a_seqno_far_below_is_a_new_log() {
        let mut d = Dataflash::new();
        let mut acts = Acts::default();
        for s in 0..=WINDOW + 1 {
            d.block(s, &data(s), at(0), &mut acts);
        }
        assert_eq!(d.block(0, &data(0), at(0), &mut acts), Verdict::NewLog);
        assert_eq!(d.block(WINDOW, &data(0), at(0), &mut acts), Verdict::Taken);
        assert_eq!(acts.duplicates, 1);
    }
}
