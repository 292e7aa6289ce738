//! The one log text of a packet, `NAME (#id) from S.C[ to S.C] (vN.0)`, as the original
//! prints it (` to 0.0` included). [`Frame`]'s `Display` and the router's log events both
//! render it through [`PacketSummary`].

use std::fmt;

use crate::address::Address;

use super::frame::Frame;
use super::header::Version;

/// The parts of a packet its log text shows, owned (log events outlive the frame).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PacketSummary {
    /// Message name.
    pub name: &'static str,
    /// Message id.
    pub message_id: u32,
    /// Sender's address.
    pub source: Address,
    /// Destination from the payload's target fields, if the message has them.
    pub target: Option<Address>,
    /// MAVLink version.
    pub version: Version,
}

impl PacketSummary {
    /// The summary of `frame`.
    #[inline]
    pub(crate) fn of(frame: &Frame<'_>) -> Self {
        PacketSummary {
            name: frame.name(),
            message_id: frame.message_id(),
            source: frame.source(),
            target: frame.target(),
            version: frame.version(),
        }
    }
}

impl fmt::Display for PacketSummary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} (#{}) from {}",
            self.name, self.message_id, self.source
        )?;
        if let Some(to) = self.target {
            write!(f, " to {to}")?;
        }
        write!(f, " (v{}.0)", self.version.number())
    }
}

/// The log text of a packet: `NAME (#id) from S.C[ to S.C] (vN.0)` (see [`PacketSummary`]).
impl fmt::Display for Frame<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(&PacketSummary::of(self), f)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ping(target: Option<Address>, version: Version) -> PacketSummary {
        PacketSummary {
            name: "PING",
            message_id: 4,
            source: Address::new(192, 168),
            target,
            version,
        }
    }

    #[test]
    fn target_0_0_is_printed_and_a_missing_one_is_not() {
        assert_eq!(
            ping(Some(Address::new(0, 0)), Version::V1).to_string(),
            "PING (#4) from 192.168 to 0.0 (v1.0)"
        );
        assert_eq!(
            ping(None, Version::V2).to_string(),
            "PING (#4) from 192.168 (v2.0)"
        );
    }

    #[test]
    fn a_frame_prints_its_summary() {
        let mut bytes = Vec::new();
        let header = crate::wire::encode::Header {
            seq: 1,
            system: 0,
            component: 255,
        };
        crate::wire::encode::encode_v2(header, 4, &[0x55; 14], None, &mut bytes)
            .expect("encodable");
        let frame = Frame::parse_exact(&bytes).expect("valid");
        let summary = PacketSummary::of(&frame);
        assert_eq!(summary.target, Some(Address::new(85, 85)));
        assert_eq!(summary.to_string(), "PING (#4) from 0.255 to 85.85 (v2.0)");
        assert_eq!(frame.to_string(), summary.to_string());
    }
}
