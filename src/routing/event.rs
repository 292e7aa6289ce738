//! What the router reports for logging, and the original's exact log texts.
//!
//! `Display` renders the message without the `YYYY-MM-DD HH:MM:SS  ` prefix, which the I/O
//! layer adds; an event of [`Event::level`] L is printed iff the log level is at least L.

use std::fmt;
use std::sync::Arc;

use super::link::LinkId;
use crate::address::Address;

/// The parts of a packet its log text shows; defined with the wire format, where
/// [`Frame`](crate::wire::Frame)'s own log text is rendered by the same code.
pub use crate::wire::PacketSummary;

/// A link as named in an event.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LinkRef {
    /// The link's id.
    pub id: LinkId,
    /// The link's name at the time of the event.
    pub name: Arc<str>,
}

/// Something the router did that the log may show.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Event {
    /// Level 1: an address was learned (or preloaded) on a link where it was not present.
    NewComponent {
        /// The address.
        address: Address,
        /// Where it was learned.
        link: LinkRef,
    },
    /// Level 2: a valid packet arrived.
    Received {
        /// The packet.
        packet: PacketSummary,
        /// Where it came from.
        source: LinkRef,
    },
    /// Level 3: the filter let the packet out to a link (it was queued there).
    Accepted {
        /// The packet.
        packet: PacketSummary,
        /// Where it came from.
        source: LinkRef,
        /// Where it goes.
        dest: LinkRef,
        /// Its priority in the destination's queue.
        priority: i32,
    },
    /// Level 3: the filter kept the packet from a link.
    Rejected {
        /// The packet.
        packet: PacketSummary,
        /// Where it came from.
        source: LinkRef,
        /// Where it did not go.
        dest: LinkRef,
    },
}

impl Event {
    /// The lowest log level (1–3) at which the original prints this event.
    pub(crate) fn level(&self) -> u8 {
        match self {
            Event::NewComponent { .. } => 1,
            Event::Received { .. } => 2,
            Event::Accepted { .. } | Event::Rejected { .. } => 3,
        }
    }
}

/// The original's log message, without the timestamp prefix.
impl fmt::Display for Event {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Event::NewComponent { address, link } => {
                write!(f, "new component {address} on {}", link.name)
            }
            Event::Received { packet, source } => {
                write!(f, "received {packet} source {}", source.name)
            }
            Event::Accepted {
                packet,
                source,
                dest,
                ..
            } => write!(
                f,
                "accepted {packet} source {} dest {}",
                source.name, dest.name
            ),
            Event::Rejected {
                packet,
                source,
                dest,
            } => write!(
                f,
                "rejected {packet} source {} dest {}",
                source.name, dest.name
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::Version;

    fn link(id: u64, name: &str) -> LinkRef {
        LinkRef {
            id: LinkId(id),
            name: name.into(),
        }
    }

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
    fn texts_and_levels_match_the_original() {
        let new = Event::NewComponent {
            address: Address::new(127, 1),
            link: link(0, "127.0.0.1:43009"),
        };
        assert_eq!(new.to_string(), "new component 127.1 on 127.0.0.1:43009");
        assert_eq!(new.level(), 1);
        let received = Event::Received {
            packet: ping(Some(Address::new(127, 1)), Version::V2),
            source: link(1, "./ttyS0"),
        };
        assert_eq!(
            received.to_string(),
            "received PING (#4) from 192.168 to 127.1 (v2.0) source ./ttyS0"
        );
        assert_eq!(received.level(), 2);
        let accepted = Event::Accepted {
            packet: PacketSummary {
                name: "PARAM_REQUEST_READ",
                message_id: 20,
                source: Address::new(10, 10),
                target: Some(Address::new(192, 168)),
                version: Version::V2,
            },
            source: link(2, "127.0.0.1:5000"),
            dest: link(3, "127.0.0.1:5001"),
            priority: 0,
        };
        assert_eq!(
            accepted.to_string(),
            "accepted PARAM_REQUEST_READ (#20) from 10.10 to 192.168 (v2.0) source 127.0.0.1:5000 dest 127.0.0.1:5001"
        );
        assert_eq!(accepted.level(), 3);
        let rejected = Event::Rejected {
            packet: PacketSummary {
                name: "HEARTBEAT",
                message_id: 0,
                source: Address::new(127, 1),
                target: None,
                version: Version::V2,
            },
            source: link(2, "127.0.0.1:5000"),
            dest: link(0, "./ttyS0"),
        };
        assert_eq!(
            rejected.to_string(),
            "rejected HEARTBEAT (#0) from 127.1 (v2.0) source 127.0.0.1:5000 dest ./ttyS0"
        );
        assert_eq!(rejected.level(), 3);
    }
}
