//! When bytes a parser holds back for an incomplete frame stop waiting for the rest.
//!
//! A sender on a serial line or in UDP datagrams writes a frame's bytes back to back, so
//! once its line has been quiet for longer than a whole largest frame takes to arrive
//! (plus a margin for USB adapters and networks that deliver in chunks), the incomplete
//! candidate is not a frame. Noise that looks like the start of a long frame would
//! otherwise hold up the valid frames behind it until enough further bytes arrive —
//! seconds on a link that only carries heartbeats.
//!
//! A TCP connection is different: it loses and corrupts nothing, and a retransmission
//! (200 ms or more on Linux) or a cellular stall may pause it in the middle of a frame.
//! Its held-back bytes are the start of the next frame until the connection says
//! otherwise — a checksum failure (the parser resynchronises) or its end — so for it
//! the rule never fires ([`StaleTail::reliable`]).

use std::time::Duration;

use crate::time::Timestamp;
use crate::wire::header::MAX_FRAME_LEN;

/// Quiet time beyond a largest frame's transmission time after which held-back bytes
/// are judged.
pub(crate) const STALE_GAP: Duration = Duration::from_millis(100);

/// The quiet-line rule of one byte stream or datagram interface.
#[derive(Debug, Clone, Copy)]
pub struct StaleTail {
    /// How long the line must be quiet (None: never, on a reliable stream).
    patience: Option<Duration>,
    /// When bytes last arrived.
    last_rx: Timestamp,
}

impl StaleTail {
    /// The rule for a line of `baudrate` (None: a datagram network, where a frame
    /// arrives at once).
    pub fn new(baudrate: Option<u32>) -> Self {
        let frame_time = baudrate.map_or(Duration::ZERO, |baud| {
            // 10 bits per byte on an 8N1 line.
            Duration::from_micros(MAX_FRAME_LEN as u64 * 10 * 1_000_000 / u64::from(baud.max(1)))
        });
        StaleTail {
            patience: Some(STALE_GAP + frame_time),
            last_rx: Timestamp::ZERO,
        }
    }

    /// The rule for a reliable byte stream (TCP): held-back bytes never go stale.
    pub(crate) fn reliable() -> Self {
        StaleTail {
            patience: None,
            last_rx: Timestamp::ZERO,
        }
    }

    /// Notes that bytes arrived at `now`.
    #[inline]
    pub(crate) fn received(&mut self, now: Timestamp) {
        self.last_rx = now;
    }

    /// When `pending` held-back bytes become stale (None when nothing is held back, or
    /// on a reliable stream).
    pub(crate) fn deadline(&self, pending: usize) -> Option<Timestamp> {
        let patience = self.patience?;
        (pending > 0).then(|| self.last_rx + patience)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn patience_covers_a_largest_frame_at_the_line_rate() {
        let mut t = StaleTail::new(Some(9600));
        t.received(Timestamp::from_secs(1));
        // 280 bytes at 9600 baud take 291.666 ms.
        assert_eq!(
            t.deadline(3),
            Some(Timestamp::from_secs(1) + Duration::from_micros(100_000 + 291_666))
        );
        assert_eq!(t.deadline(0), None);
        let udp = StaleTail::new(None);
        assert_eq!(udp.deadline(1), Some(Timestamp::ZERO + STALE_GAP));
    }

    #[test]
    fn a_reliable_stream_never_gives_up_on_held_back_bytes() {
        let mut tcp = StaleTail::reliable();
        tcp.received(Timestamp::from_secs(1));
        assert_eq!(tcp.deadline(1), None);
        assert_eq!(tcp.deadline(279), None);
    }
}
