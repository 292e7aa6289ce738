//! MAVLink addresses: a `system.component` pair of octets.

use std::fmt;

/// A MAVLink address, written `system.component` (e.g. `192.168`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct Address {
    /// System id (0 = broadcast to every system).
    pub system: u8,
    /// Component id (0 = broadcast to every component of the system).
    pub component: u8,
}

impl Address {
    /// Builds an address from its two octets.
    pub const fn new(system: u8, component: u8) -> Self {
        Address { system, component }
    }

    /// The address as one 16-bit number, system in the high byte (used by subnet masks).
    pub(crate) const fn to_u16(self) -> u16 {
        ((self.system as u16) << 8) | self.component as u16
    }

    /// Inverse of [`Address::to_u16`].
    pub(crate) const fn from_u16(v: u16) -> Self {
        Address::new((v >> 8) as u8, v as u8)
    }
}

impl fmt::Display for Address {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}.{}", self.system, self.component)
    }
}

mod subnet;
pub use subnet::{PrefixMask, Subnet, SubnetParseError};
