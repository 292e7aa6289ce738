//! The core's side of recording: frames the engine took in, with their time of arrival
//! on the core's clock, held until the event loop takes them (every loop turn). Bounded,
//! so that a loop that never takes them cannot grow memory: beyond the bound frames are
//! counted and not kept. Routing never depends on it.

use super::filter::RecordFilter;
use crate::time::Timestamp;
use crate::wire::Frame;

/// What the tap holds at most between two takes: far more than one loop turn receives.
pub(crate) const TAP_BOUND: usize = 1 << 20;

/// Frames waiting to be recorded.
#[derive(Debug, Default)]
pub struct Tap {
    filter: RecordFilter,
    /// The frames back to back.
    bytes: Vec<u8>,
    /// Time of arrival and length of each frame in `bytes`, in order.
    records: Vec<(Timestamp, u16)>,
    /// Frames not kept because the tap was full.
    dropped: u64,
}

impl Tap {
    /// A tap keeping the frames `filter` passes.
    pub fn new(filter: RecordFilter) -> Self {
        Tap {
            filter,
            ..Tap::default()
        }
    }

    /// Keeps `frame`, which arrived at `now` (signed and verified, or not), if the filter
    /// passes it and there is room.
    #[inline]
    pub(crate) fn offer(&mut self, frame: &Frame<'_>, signed: bool, now: Timestamp) {
        if !self.filter.matches(frame, signed) {
            return;
        }
        let bytes = frame.as_bytes();
        let Ok(len) = u16::try_from(bytes.len()) else {
            return;
        };
        if self.bytes.len() + bytes.len() > TAP_BOUND {
            self.dropped += 1;
            return;
        }
        self.bytes.extend_from_slice(bytes);
        self.records.push((now, len));
    }

    /// True when no frame is waiting.
    #[inline]
    pub(crate) fn is_empty(&self) -> bool {
        self.records.is_empty()
    }

    /// Hands every waiting frame to `take` with its time of arrival, oldest first, and
    /// forgets them.
    pub(crate) fn drain(&mut self, take: &mut impl FnMut(Timestamp, &[u8])) {
        let mut at = 0;
        for &(now, len) in &self.records {
            let end = at + usize::from(len);
            if let Some(frame) = self.bytes.get(at..end) {
                take(now, frame);
            }
            at = end;
        }
        self.records.clear();
        self.bytes.clear();
    }

    /// Frames not kept because the tap was full.
    pub fn dropped(&self) -> u64 {
        self.dropped
    }
}
