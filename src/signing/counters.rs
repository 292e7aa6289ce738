//! What signing did on one link or interface, and its part of the counters report.

use std::fmt;

use super::verify::Refusal;

/// Frames checked, refused and signed by the router.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SigningCounters {
    /// Signed frames that passed the check.
    pub verified: u64,
    /// Refused: the signature did not match.
    pub bad_signature: u64,
    /// Refused: the timestamp was not after the stream's last.
    pub replayed: u64,
    /// Refused: the timestamp was too far from the router's clock.
    pub out_of_window: u64,
    /// Refused: not signed on an interface that requires signatures.
    pub unsigned: u64,
    /// Frames the router signed on their way out.
    pub signed_out: u64,
}

impl SigningCounters {
    /// Counts a refusal.
    pub(crate) fn refused(&mut self, why: Refusal) {
        let n = match why {
            Refusal::BadSignature => &mut self.bad_signature,
            Refusal::Replayed => &mut self.replayed,
            Refusal::OutOfWindow => &mut self.out_of_window,
            Refusal::Unsigned => &mut self.unsigned,
        };
        *n += 1;
    }

    /// Frames refused for any reason.
    pub fn refused_total(&self) -> u64 {
        self.bad_signature + self.replayed + self.out_of_window + self.unsigned
    }

    /// True if nothing was counted.
    pub(crate) fn is_zero(&self) -> bool {
        *self == SigningCounters::default()
    }
}

impl std::ops::AddAssign for SigningCounters {
    fn add_assign(&mut self, other: SigningCounters) {
        self.verified += other.verified;
        self.bad_signature += other.bad_signature;
        self.replayed += other.replayed;
        self.out_of_window += other.out_of_window;
        self.unsigned += other.unsigned;
        self.signed_out += other.signed_out;
    }
}

impl fmt::Display for SigningCounters {
    /// `signing: 5 verified, 1 bad signature, 2 replayed, 1 out of window, 3 unsigned
    /// dropped, 7 signed`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "signing: {} verified, {} bad signature, {} replayed, {} out of window, {} unsigned dropped, {} signed",
            self.verified,
            self.bad_signature,
            self.replayed,
            self.out_of_window,
            self.unsigned,
            self.signed_out
        )
    }
}
