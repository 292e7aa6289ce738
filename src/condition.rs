//! The `if …` part of a filter rule and of a `record { only if … }` statement: what a
//! packet must be (signed or not, its message id, its source and destination subnets).
//! Below both users: the configuration holds it, the filter chains and the recording
//! filter test packets against it.

use crate::address::{Address, Subnet};

/// `if [signed|unsigned] [TYPE] [from SUBNET] [to SUBNET]`: every part present must match.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Condition {
    /// `Some(true)`: the packet must be signed (`signed`); `Some(false)`: unsigned.
    pub signed: Option<bool>,
    /// Message id the packet must have.
    pub message_id: Option<u32>,
    /// Subnet the packet's source address must be in.
    pub source: Option<Subnet>,
    /// Subnet the destination being filtered for must be in.
    pub dest: Option<Subnet>,
}

impl Condition {
    /// Whether a packet with `message_id` from `source`, being sent towards `dest`,
    /// matches; `signed` tells whether it arrived signed (and its signature was accepted).
    pub fn matches(&self, message_id: u32, source: Address, dest: Address, signed: bool) -> bool {
        self.signed.is_none_or(|s| s == signed)
            && self.message_id.is_none_or(|id| id == message_id)
            && self.source.is_none_or(|s| s.contains(source))
            && self.dest.is_none_or(|d| d.contains(dest))
    }
}
