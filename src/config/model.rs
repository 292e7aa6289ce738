//! The meaning of a configuration: typed, validated values the router runs from.

use crate::address::Address;
pub use crate::condition::Condition;
use crate::dialect::Dialect;
use crate::wire::Checks;
use std::net::{IpAddr, Ipv4Addr, Ipv6Addr, SocketAddr};
use std::path::PathBuf;

pub use super::net::{Host, IpRange, Remote};
pub use super::paths::{Heartbeat, InterfaceGroup};
pub use super::rate::Rate;
use std::time::Duration;

/// A whole, valid configuration.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Config {
    /// What happens to a packet the chains do not decide on (default: reject).
    pub default_action: DefaultAction,
    /// UDP, TCP and serial interfaces in file order.
    pub interfaces: Vec<Interface>,
    /// Every chain, in order of first mention; rules of repeated `chain X` blocks are joined.
    pub chains: Vec<Chain>,
    /// The chain every packet starts in (`default`; empty when the file has none).
    pub default_chain: ChainId,
    /// How many bytes the outgoing queues may hold (the `queue` block).
    pub queue: QueueBounds,
    /// Where the signing timestamps are saved (`signing_state PATH;`), as written; see
    /// [`Config::signing_state_path`] for the default.
    pub signing_state: Option<String>,
    /// The `record` block: what to record where; `None` records nothing.
    pub record: Option<Recording>,
    /// The statistics endpoint (the `stats` block), if configured.
    pub stats: Option<StatsEndpoint>,
    /// The messages known: the built-in table plus the `dialect` files.
    pub dialect: Dialect,
    /// The files of the `dialect` statements, resolved, in order.
    pub dialect_files: Vec<PathBuf>,
    /// What becomes of frames whose id no dialect defines (`unknown_messages`).
    pub unknown_messages: UnknownMessages,
    /// `dedup DURATION;`: a frame byte-identical to one received within this window
    /// (on any link) is dropped; `None`: no deduplication.
    pub dedup: Option<Duration>,
    /// The `group NAME;` statements of interface blocks, in file order.
    pub groups: Vec<InterfaceGroup>,
    /// The router's own heartbeat (the `heartbeat` block), if configured.
    pub heartbeat: Option<Heartbeat>,
    /// The autopilot's flight log streamed to the router (the `flight_log` block).
    pub flight_log: Option<super::FlightLog>,
}

/// `unknown_messages accept|reject;`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum UnknownMessages {
    /// Dropped and counted (the default).
    #[default]
    Reject,
    /// Forwarded byte for byte as broadcasts, through the chains (rules name them
    /// `UNKNOWN`); their checksum cannot be checked.
    Accept,
}

impl Config {
    /// A configuration of `interfaces` only: every packet is accepted (`default_action
    /// accept`, an empty `default` chain) and the queues keep their default bounds. What
    /// command-line endpoints run.
    pub(crate) fn accept_all(interfaces: Vec<Interface>) -> Self {
        Config {
            default_action: DefaultAction::Accept,
            interfaces,
            chains: vec![Chain {
                name: "default".to_string(),
                rules: Vec::new(),
            }],
            default_chain: ChainId(0),
            queue: QueueBounds::default(),
            signing_state: None,
            record: None,
            stats: None,
            dialect: Dialect::builtin(),
            dialect_files: Vec::new(),
            unknown_messages: UnknownMessages::Reject,
            dedup: None,
            groups: Vec::new(),
            heartbeat: None,
            flight_log: None,
        }
    }

    /// What the parsers of this configuration check: as a router does, plus frames of
    /// unknown ids under `unknown_messages accept;`.
    pub fn checks(&self) -> Checks {
        Checks {
            accept_unknown: self.unknown_messages == UnknownMessages::Accept,
            ..Checks::ROUTING
        }
    }

    /// Where the router saves the signing timestamps of its streams: `None` when no
    /// interface has a `signing_key`; else the `signing_state` path, or by default
    /// `signing.state` in `$STATE_DIRECTORY` (the first of its directories; systemd sets
    /// it for `StateDirectory=`), or `/var/lib/mavtables/signing.state` when that is
    /// unset. `env` looks up an environment variable.
    pub fn signing_state_path(&self, env: impl Fn(&str) -> Option<String>) -> Option<PathBuf> {
        if !self.interfaces.iter().any(|i| i.signing().is_some()) {
            return None;
        }
        if let Some(path) = &self.signing_state {
            return Some(PathBuf::from(path));
        }
        let state_dir = env("STATE_DIRECTORY")
            .and_then(|dirs| dirs.split(':').next().map(str::to_string))
            .filter(|dir| !dir.is_empty());
        Some(match state_dir {
            Some(dir) => PathBuf::from(dir).join(SIGNING_STATE_FILE),
            None => PathBuf::from(DEFAULT_STATE_DIRECTORY).join(SIGNING_STATE_FILE),
        })
    }

    /// The chain with id `id`.
    pub fn chain(&self, id: ChainId) -> &Chain {
        &self.chains[id.0]
    }

    /// The chain named `name`, if there is one.
    pub fn chain_by_name(&self, name: &str) -> Option<ChainId> {
        self.chains.iter().position(|c| c.name == name).map(ChainId)
    }
}

/// The file name of the signing state in its state directory.
pub const SIGNING_STATE_FILE: &str = "signing.state";

/// The state directory when `$STATE_DIRECTORY` is not set.
pub const DEFAULT_STATE_DIRECTORY: &str = "/var/lib/mavtables";

/// The fallback decision when no rule decides.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DefaultAction {
    /// Forward the packet (priority 0).
    Accept,
    /// Drop the packet.
    #[default]
    Reject,
}

/// One `udp`, `tcp`, `serial` or `zenoh` block.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Interface {
    /// A UDP socket (server or client).
    Udp(UdpInterface),
    /// A serial port.
    Serial(SerialInterface),
    /// A TCP listener or a TCP connection to one peer.
    Tcp(TcpInterface),
    /// A WebSocket server: every connection a browser makes is a link.
    WebSocket(WebSocketInterface),
    /// A Zenoh session: one link, frames published and subscribed by key.
    Zenoh(ZenohInterface),
}

impl Interface {
    /// The block's signing settings, when it has a `signing_key`.
    pub fn signing(&self) -> Option<&InterfaceSigning> {
        match self {
            Interface::Udp(u) => u.signing.as_ref(),
            Interface::Serial(s) => s.signing.as_ref(),
            Interface::Tcp(t) => t.signing.as_ref(),
            Interface::WebSocket(w) => w.signing.as_ref(),
            Interface::Zenoh(z) => z.signing.as_ref(),
        }
    }
}

/// How a Zenoh interface joins the Zenoh network (`mode client|peer;`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ZenohMode {
    /// Through a Zenoh router it connects to (the default).
    #[default]
    Client,
    /// Directly to other peers, by `connect` and `listen`.
    Peer,
}

/// What a Zenoh interface subscribes to (`receive addressed|all;`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ZenohReceive {
    /// Broadcasts and frames addressed to the systems behind the router (an edge; the
    /// default): the subscriptions follow the systems its other links reach.
    #[default]
    Addressed,
    /// Everything under the prefix (a ground-station site).
    All,
}

/// A `zenoh { }` block with its defaults filled in.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ZenohInterface {
    /// Client of a Zenoh router, or peer.
    pub mode: ZenohMode,
    /// Endpoints to connect to (`tcp/HOST:PORT`), as written.
    pub connect: Vec<String>,
    /// Endpoints to listen on, as written.
    pub listen: Vec<String>,
    /// The first chunks of every key (default `mavtables`).
    pub prefix: String,
    /// What it subscribes to.
    pub receive: ZenohReceive,
    /// MAVLink 2 signing, when the block has a `signing_key`.
    pub signing: Option<InterfaceSigning>,
}

impl Default for ZenohInterface {
    /// `zenoh {}`: a client of no Zenoh router yet, under the default prefix.
    fn default() -> Self {
        ZenohInterface {
            mode: ZenohMode::default(),
            connect: Vec::new(),
            listen: Vec::new(),
            prefix: Self::DEFAULT_PREFIX.to_string(),
            receive: ZenohReceive::default(),
            signing: None,
        }
    }
}

impl ZenohInterface {
    /// The prefix when the block names none.
    pub const DEFAULT_PREFIX: &'static str = "mavtables";

    /// How messages and counters name it: `zenoh PREFIX`.
    pub(crate) fn label(&self) -> String {
        format!("zenoh {}", self.prefix)
    }
}

/// The MAVLink 2 signing of one interface: `signing_key PATH;` and `allow_unsigned`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct InterfaceSigning {
    /// The key file's path, as written (read when the router starts).
    pub key_file: String,
    /// `allow_unsigned yes;`: unsigned packets received on the interface are let in
    /// (default no: they are dropped).
    pub allow_unsigned: bool,
}

/// How many remotes a server block takes when `max_peers` is not given.
pub const DEFAULT_MAX_PEERS: usize = 128;

/// Which remotes a server interface takes as links.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PeerLimits {
    /// At most this many remotes are links at once (1 – 65535).
    pub max_peers: usize,
    /// Remotes must be in one of these ranges; empty means any address.
    pub allow: Vec<IpRange>,
}

impl Default for PeerLimits {
    fn default() -> Self {
        PeerLimits {
            max_peers: DEFAULT_MAX_PEERS,
            allow: Vec::new(),
        }
    }
}

impl PeerLimits {
    /// Whether a remote at `ip` may become a link (by address; the count is the driver's).
    pub fn allows(&self, ip: IpAddr) -> bool {
        self.allow.is_empty() || self.allow.iter().any(|r| r.contains(ip))
    }
}

/// A `udp { }` block with its defaults filled in: a server (no `connect`) that answers
/// every remote that sends to it, or a client that sends to `connect` from the start.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UdpInterface {
    /// Server: port to listen on (default 14500); client: local port (default 0 = any).
    pub port: u16,
    /// Local address; `None` = every address (0.0.0.0, or :: for an IPv6 peer).
    pub address: Option<IpAddr>,
    /// Transmit limit in bits per second; `None` (also for `max_bitrate 0`) means no limit.
    pub max_bitrate: Option<u64>,
    /// `Some` makes the block a client of this remote.
    pub connect: Option<Remote>,
    /// Which remotes a server takes (defaults for a client, where it has no effect).
    pub peers: PeerLimits,
    /// MAVLink 2 signing, when the block has a `signing_key`.
    pub signing: Option<InterfaceSigning>,
}

impl Default for UdpInterface {
    fn default() -> Self {
        UdpInterface {
            port: 14500,
            address: None,
            max_bitrate: None,
            connect: None,
            peers: PeerLimits::default(),
            signing: None,
        }
    }
}

impl UdpInterface {
    /// The address to bind: `address`, else every address of the peer's family (IPv4
    /// unless the block connects to an IPv6 address).
    pub fn local_address(&self) -> IpAddr {
        local_address(self.address, self.connect.as_ref())
    }

    /// How messages and counters name it: `udp ADDRESS:PORT` for a server, `udp connect
    /// HOST:PORT` for a client.
    pub(crate) fn label(&self) -> String {
        match &self.connect {
            None => format!("udp {}", SocketAddr::new(self.local_address(), self.port)),
            Some(remote) => format!("udp connect {remote}"),
        }
    }
}

/// A `tcp { }` block with its defaults filled in: a server (no `connect`) where every
/// accepted connection is a link of its own, or a client of one remote.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TcpInterface {
    /// Server: port to listen on (default 5760); unused by a client.
    pub port: u16,
    /// Server: address to listen on; client: address to connect from. `None` = every
    /// address (0.0.0.0, or :: for an IPv6 peer).
    pub address: Option<IpAddr>,
    /// Transmit limit in bits per second; `None` (also for `max_bitrate 0`) means no limit.
    pub max_bitrate: Option<u64>,
    /// `Some` makes the block a client of this remote.
    pub connect: Option<Remote>,
    /// Which remotes a server takes (defaults for a client, where it has no effect).
    pub peers: PeerLimits,
    /// MAVLink 2 signing, when the block has a `signing_key`.
    pub signing: Option<InterfaceSigning>,
}

impl TcpInterface {
    /// The port a `tcp` server listens on unless `port` says otherwise.
    pub const DEFAULT_PORT: u16 = 5760;

    /// The address to bind: `address`, else every address of the peer's family.
    pub fn local_address(&self) -> IpAddr {
        local_address(self.address, self.connect.as_ref())
    }

    /// How messages and counters name it: `tcp ADDRESS:PORT` for a server, `tcp connect
    /// HOST:PORT` for a client.
    pub(crate) fn label(&self) -> String {
        match &self.connect {
            None => format!("tcp {}", SocketAddr::new(self.local_address(), self.port)),
            Some(remote) => format!("tcp connect {remote}"),
        }
    }
}

impl Default for TcpInterface {
    fn default() -> Self {
        TcpInterface {
            port: Self::DEFAULT_PORT,
            address: None,
            max_bitrate: None,
            connect: None,
            peers: PeerLimits::default(),
            signing: None,
        }
    }
}

/// A `websocket { }` block with its defaults filled in: a server where every connection
/// (a browser's, once its WebSocket handshake is done) is a link of its own.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct WebSocketInterface {
    /// Port to listen on (default 8765).
    pub port: u16,
    /// Address to listen on; `None` = every IPv4 address (0.0.0.0).
    pub address: Option<IpAddr>,
    /// Transmit limit of each connection in bits per second; `None` means no limit.
    pub max_bitrate: Option<u64>,
    /// Which remotes it takes.
    pub peers: PeerLimits,
    /// MAVLink 2 signing, when the block has a `signing_key`.
    pub signing: Option<InterfaceSigning>,
    /// `origin` statements, in lower case: a browser's request whose `Origin` header
    /// names none of them is refused. Empty: any origin. Requests without the header
    /// (not made by a web page) are taken either way.
    pub origins: Vec<String>,
}

impl WebSocketInterface {
    /// The port a `websocket` server listens on unless `port` says otherwise.
    pub const DEFAULT_PORT: u16 = 8765;

    /// The address to bind: `address`, else every IPv4 address.
    pub fn local_address(&self) -> IpAddr {
        local_address(self.address, None)
    }

    /// How messages and counters name it: `websocket ADDRESS:PORT`.
    pub(crate) fn label(&self) -> String {
        format!(
            "websocket {}",
            SocketAddr::new(self.local_address(), self.port)
        )
    }
}

impl Default for WebSocketInterface {
    fn default() -> Self {
        WebSocketInterface {
            port: Self::DEFAULT_PORT,
            address: None,
            max_bitrate: None,
            peers: PeerLimits::default(),
            signing: None,
            origins: Vec::new(),
        }
    }
}

fn local_address(address: Option<IpAddr>, connect: Option<&Remote>) -> IpAddr {
    match (address, connect) {
        (Some(ip), _) => ip,
        (
            None,
            Some(Remote {
                host: Host::Ip(IpAddr::V6(_)),
                ..
            }),
        ) => IpAddr::V6(Ipv6Addr::UNSPECIFIED),
        (None, _) => IpAddr::V4(Ipv4Addr::UNSPECIFIED),
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
    /// Transmit limit in bits per second; `None` (also for `max_bitrate 0`) means no limit.
    pub max_bitrate: Option<u64>,
    /// MAVLink 2 signing, when the block has a `signing_key`.
    pub signing: Option<InterfaceSigning>,
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

/// The `record { }` block: every valid frame the router takes in (or those meeting one of
/// `only`) is written to `.tlog` files named after `path`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Recording {
    /// The file-name pattern as written (`%Y %m %d %H %M %S %%`, local time); see
    /// [`Recording::path_pattern`] for the default.
    pub path: Option<String>,
    /// A file is closed for a new one before it would grow beyond this many bytes.
    pub max_file_bytes: u64,
    /// At most this many recordings of the pattern are kept in the directory (the
    /// oldest are removed); 0: no limit.
    pub max_files: u32,
    /// Recording keeps this many bytes free on the disk: older recordings are removed,
    /// and when that is not enough records are dropped until there is room again.
    pub min_free_bytes: u64,
    /// Record only frames meeting one of these (`only if …;`); empty: every frame.
    pub only: Vec<Condition>,
}

impl Recording {
    /// `max_file_bytes` unless written: 100 MB.
    pub const DEFAULT_MAX_FILE_BYTES: u64 = 100_000_000;
    /// The smallest `max_file_bytes`: room for a few of the largest records.
    pub const MIN_FILE_BYTES: u64 = 1024;
    /// `max_files` unless written.
    pub const DEFAULT_MAX_FILES: u32 = 100;
    /// `min_free_bytes` unless written: 100 MB.
    pub const DEFAULT_MIN_FREE_BYTES: u64 = 100_000_000;
    /// The file name when `path` is not written.
    pub const DEFAULT_NAME: &str = "%Y-%m-%d_%H-%M-%S.tlog";
    /// The directory when `path` is not written and `$LOGS_DIRECTORY` is unset.
    pub const DEFAULT_DIRECTORY: &str = "/var/log/mavtables";

    /// A block with every default and no path.
    pub fn with_defaults() -> Self {
        Recording {
            path: None,
            max_file_bytes: Self::DEFAULT_MAX_FILE_BYTES,
            max_files: Self::DEFAULT_MAX_FILES,
            min_free_bytes: Self::DEFAULT_MIN_FREE_BYTES,
            only: Vec::new(),
        }
    }

    /// The path pattern recordings are written to: `path`, or by default
    /// `%Y-%m-%d_%H-%M-%S.tlog` in `$LOGS_DIRECTORY` (the first of its directories; systemd
    /// sets it for `LogsDirectory=`), else in `/var/log/mavtables`. `env` looks up an
    /// environment variable.
    pub fn path_pattern(&self, env: impl Fn(&str) -> Option<String>) -> String {
        if let Some(path) = &self.path {
            return path.clone();
        }
        let dir = env("LOGS_DIRECTORY")
            .and_then(|dirs| dirs.split(':').next().map(str::to_string))
            .filter(|dir| !dir.is_empty())
            .unwrap_or_else(|| Self::DEFAULT_DIRECTORY.to_string());
        format!("{}/{}", dir.trim_end_matches('/'), Self::DEFAULT_NAME)
    }
}

/// The `stats { address IP; port N; allow RANGE; }` block: where the HTTP statistics
/// endpoint (`/metrics`, `/stats`, the status page) listens, and who may ask it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StatsEndpoint {
    /// The address to listen on (default 127.0.0.1: this machine only).
    pub address: IpAddr,
    /// The TCP port (default [`StatsEndpoint::DEFAULT_PORT`]).
    pub port: u16,
    /// Clients must be in one of these ranges; empty means any address.
    pub allow: Vec<IpRange>,
}

impl StatsEndpoint {
    /// The port when the block gives none.
    pub const DEFAULT_PORT: u16 = 9100;

    /// Whether a client at `ip` may ask (an IPv4 client seen by an IPv6 socket counts
    /// as its IPv4 address).
    pub fn allows(&self, ip: IpAddr) -> bool {
        let ip = match ip {
            IpAddr::V6(v6) => v6.to_ipv4_mapped().map_or(ip, IpAddr::V4),
            v4 => v4,
        };
        self.allow.is_empty() || self.allow.iter().any(|r| r.contains(ip))
    }
}

impl Default for StatsEndpoint {
    fn default() -> Self {
        StatsEndpoint {
            address: IpAddr::V4(Ipv4Addr::LOCALHOST),
            port: Self::DEFAULT_PORT,
            allow: Vec::new(),
        }
    }
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
    /// `with rate R`: at most this many packets the rule accepts pass per destination
    /// link, source component and message id (`accept` rules only; see [`Rate`]).
    pub rate: Option<Rate>,
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
