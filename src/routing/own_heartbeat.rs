//! The router's own HEARTBEAT (the `heartbeat` block): some autopilots (PX4 on USB)
//! stay silent until they hear one. Built here on the core's own deadline and sent to
//! every link through the normal queues; the core never reads a clock.

use std::time::Duration;

use crate::address::Address;
use crate::config::Heartbeat;
use crate::time::Timestamp;
use crate::wire::encode::{Header, encode_v2};

/// HEARTBEAT's message id.
const HEARTBEAT_ID: u32 = 0;
/// MAV_TYPE_ONBOARD_CONTROLLER.
pub const TYPE_ONBOARD_CONTROLLER: u8 = 18;
/// MAV_AUTOPILOT_INVALID: not an autopilot.
pub const AUTOPILOT_INVALID: u8 = 8;
/// MAV_STATE_ACTIVE.
pub const STATE_ACTIVE: u8 = 4;
/// The `mavlink_version` field of MAVLink 2 heartbeats.
pub const MAVLINK_VERSION: u8 = 3;

/// The schedule and sequence of the router's heartbeat.
#[derive(Debug, Clone)]
pub(crate) struct OwnHeartbeat {
    address: Address,
    interval: Duration,
    next: Timestamp,
    /// When the last heartbeat went.
    last: Option<Timestamp>,
    seq: u8,
}

impl OwnHeartbeat {
    /// A heartbeat as `config` says, the first due at `now`.
    pub(crate) fn new(config: &Heartbeat, now: Timestamp) -> Self {
        OwnHeartbeat {
            address: Address::new(config.system, config.component),
            interval: config.interval,
            next: now,
            last: None,
            seq: 0,
        }
    }

    /// Takes a new configuration (a reload): the sequence goes on; a new interval
    /// counts from the last heartbeat.
    pub(crate) fn reconfigure(&mut self, config: &Heartbeat) {
        if self.interval != config.interval {
            self.next = self.last.map_or(self.next, |last| last + config.interval);
            self.interval = config.interval;
        }
        self.address = Address::new(config.system, config.component);
    }

    /// The router's address as the heartbeat's source.
    pub(crate) fn address(&self) -> Address {
        self.address
    }

    /// When the next heartbeat is due.
    pub(crate) fn due(&self) -> Timestamp {
        self.next
    }

    /// The heartbeat due at `now`, if one is: one frame however late (no burst after a
    /// stall); the next is due one interval after the one it replaces, or after `now`
    /// when the core was asleep longer than that.
    pub(crate) fn take(&mut self, now: Timestamp) -> Option<Vec<u8>> {
        if now < self.next {
            return None;
        }
        self.next = (self.next + self.interval).max(now);
        if self.next == now {
            self.next = now + self.interval;
        }
        self.last = Some(now);
        let frame = build(self.address, self.seq);
        self.seq = self.seq.wrapping_add(1);
        Some(frame)
    }
}

/// A MAVLink 2 HEARTBEAT of an onboard controller from `address` with sequence `seq`.
pub(crate) fn build(address: Address, seq: u8) -> Vec<u8> {
    // Wire order: custom_mode (u32), type, autopilot, base_mode, system_status,
    // mavlink_version.
    let payload = [
        0,
        0,
        0,
        0,
        TYPE_ONBOARD_CONTROLLER,
        AUTOPILOT_INVALID,
        0,
        STATE_ACTIVE,
        MAVLINK_VERSION,
    ];
    let header = Header {
        seq,
        system: address.system,
        component: address.component,
    };
    let mut out = Vec::with_capacity(21);
    // HEARTBEAT is in every dialect and the payload is its length: this cannot fail.
    let _ = encode_v2(header, HEARTBEAT_ID, &payload, None, &mut out);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::Frame;

    #[test]
    fn the_frame_parses_as_a_heartbeat() {
        let bytes = build(Address::new(1, 191), 7);
        let frame = Frame::parse_exact(&bytes).expect("valid frame");
        assert_eq!(frame.message_id(), 0);
        assert_eq!(frame.seq(), 7);
        assert_eq!(frame.source(), Address::new(1, 191));
        assert_eq!(frame.payload(), &[0, 0, 0, 0, 18, 8, 0, 4, 3]);
    }

    #[test]
    fn one_per_interval_and_no_burst_after_a_stall() {
        let config = Heartbeat::default();
        let mut h = OwnHeartbeat::new(&config, Timestamp::ZERO);
        assert!(h.take(Timestamp::ZERO).is_some());
        assert!(h.take(Timestamp::from_millis(999)).is_none());
        assert!(h.take(Timestamp::from_millis(1000)).is_some());
        assert!(h.take(Timestamp::from_secs(10)).is_some());
        assert!(h.take(Timestamp::from_secs(10)).is_none());
        assert_eq!(h.due(), Timestamp::from_secs(11));
    }
}
