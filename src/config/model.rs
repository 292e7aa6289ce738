//! The meaning of a configuration: typed, validated values the router runs from.

use crate::address::{Address, Subnet};
use std::net::Ipv4Addr;

/// A whole, valid configuration.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Config {
    /// What happens to a packet the chains do not decide on (default: reject).
    pub default_action: DefaultAction,
    /// UDP and serial interfaces in file order.
    pub interfaces: Vec<Interface>,
    /// Every chain, in order of first mention; rules of repeated `chain X` blocks are joined.
    pub chains: Vec<Chain>,
    /// The chain every packet starts in (`default`; empty when the file has none).
    pub default_chain: ChainId,
    /// How many bytes the outgoing queues may hold (the `queue` block).
    pub queue: QueueBounds,
}

impl Config {
    /// The chain with id `id`.
    pub fn chain(&self, id: ChainId) -> &Chain {
        &self.chains[id.0]
    }

    /// The chain named `name`, if there is one.
    pub fn chain_by_name(&self, name: &str) -> Option<ChainId> {
        self.chains.iter().position(|c| c.name == name).map(ChainId)
    }
}

/// The fallback decision when no rule decides.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DefaultAction {
    /// Forward the packet (priority 0).
    Accept,
    /// Drop the packet.
    #[default]
    Reject,
}

/// One `udp` or `serial` block.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Interface {
    /// A UDP socket.
    Udp(UdpInterface),
    /// A serial port.
    Serial(SerialInterface),
}

/// A `udp { }` block with its defaults filled in.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UdpInterface {
    /// Port to listen on (default 14500).
    pub port: u16,
    /// Address to listen on (default 0.0.0.0, every address).
    pub address: Ipv4Addr,
    /// Transmit limit in bits per second; `None` (also for `max_bitrate 0`) means no limit.
    pub max_bitrate: Option<u64>,
}

impl Default for UdpInterface {
    fn default() -> Self {
        UdpInterface {
            port: 14500,
            address: Ipv4Addr::UNSPECIFIED,
            max_bitrate: None,
        }
    }
}

/// A `serial { }` block with its defaults filled in.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SerialInterface {
    /// Device path exactly as written (also the connection's name in logs).
    pub device: String,
    /// Baud rate (default 9600).
    pub baudrate: u32,
    /// Hardware flow control (default off).
    pub flow_control: bool,
    /// Addresses known to be reachable on this port before they send anything.
    pub preload: Vec<Address>,
}

/// The `queue { link_bytes N; total_bytes N; }` block: how many bytes of packets (each
/// counted with its bookkeeping) may wait to be sent. `None` leaves the routing core's
/// default: 4 MiB per link, 16 MiB in all. When a queue is full, the lowest-priority,
/// oldest packet is dropped and counted.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct QueueBounds {
    /// What one link's queue may hold.
    pub link_bytes: Option<usize>,
    /// What all queues together may hold (at least `link_bytes` when both are given).
    pub total_bytes: Option<usize>,
}

impl QueueBounds {
    /// The smallest bound: one largest MAVLink frame (280 bytes) plus the 32 bytes of
    /// bookkeeping the core counts per packet, so a queue can always hold one packet.
    pub const MIN_BYTES: u64 = 280 + 32;
    /// The largest bound, 2^40 bytes (1 TiB): far beyond any real memory, low enough that
    /// sums over many links cannot overflow.
    pub const MAX_BYTES: u64 = 1 << 40;
}

/// Index of a chain in [`Config::chains`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ChainId(pub usize);

/// A named, ordered list of rules.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Chain {
    /// The chain's name.
    pub name: String,
    /// Rules in evaluation order.
    pub rules: Vec<Rule>,
}

/// One rule: when the condition matches, the action decides.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Rule {
    /// What to do on a match.
    pub action: Action,
    /// Priority given to an accepted packet; always `None` on `reject` rules (a priority
    /// written there has no effect).
    pub priority: Option<i32>,
    /// When the rule applies (the default condition matches every packet).
    pub condition: Condition,
}

/// The action of a rule.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Action {
    /// Forward the packet.
    Accept,
    /// Drop the packet.
    Reject,
    /// Evaluate the chain; if it does not decide, continue with the next rule.
    Call(ChainId),
    /// Evaluate the chain; if it does not decide, the default action applies.
    Goto(ChainId),
}

/// `if [TYPE] [from SUBNET] [to SUBNET]`: every part present must match.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Condition {
    /// Message id the packet must have.
    pub message_id: Option<u32>,
    /// Subnet the packet's source address must be in.
    pub source: Option<Subnet>,
    /// Subnet the destination being filtered for must be in.
    pub dest: Option<Subnet>,
}

impl Condition {
    /// Whether a packet with `message_id` from `source`, being sent towards `dest`, matches.
    pub fn matches(&self, message_id: u32, source: Address, dest: Address) -> bool {
        self.message_id.is_none_or(|id| id == message_id)
            && self.source.is_none_or(|s| s.contains(source))
            && self.dest.is_none_or(|d| d.contains(dest))
    }
}
