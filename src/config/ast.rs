//! The syntax tree of a configuration file: what was written, where, with no meaning
//! attached yet. Every piece of text is kept as a [`Span`] into the source so that the
//! `--ast` printer can show it raw and later checks can point at it.

use super::Span;

/// A parsed configuration file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Ast<'a> {
    /// The source text the spans point into.
    pub src: &'a str,
    /// Top-level statements and blocks in file order.
    pub items: Vec<Item>,
}

impl<'a> Ast<'a> {
    /// The source text of `span`.
    pub(crate) fn text(&self, span: Span) -> &'a str {
        self.src.get(span.start..span.end).unwrap_or("")
    }
}

/// A top-level statement or block.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Item {
    /// `default_action accept|reject;`
    DefaultAction {
        /// The `default_action` keyword.
        keyword: Span,
        /// The value word.
        value: Span,
        /// True for `accept`.
        accept: bool,
    },
    /// `udp { ... }`
    Udp {
        /// The `udp` keyword.
        keyword: Span,
        /// Statements in order.
        settings: Vec<SocketSetting>,
    },
    /// `tcp { ... }`: the same statements as `udp`.
    Tcp {
        /// The `tcp` keyword.
        keyword: Span,
        /// Statements in order.
        settings: Vec<SocketSetting>,
    },
    /// `websocket { ... }`: a server for browsers; the statements of `tcp` but `connect`.
    WebSocket {
        /// The `websocket` keyword.
        keyword: Span,
        /// Statements in order.
        settings: Vec<SocketSetting>,
    },
    /// `zenoh { ... }`: a Zenoh interface (feature `zenoh`).
    Zenoh {
        /// The `zenoh` keyword.
        keyword: Span,
        /// Statements in order.
        settings: Vec<ZenohSetting>,
    },
    /// `serial { ... }`
    Serial {
        /// The `serial` keyword.
        keyword: Span,
        /// Statements in order.
        settings: Vec<SerialSetting>,
    },
    /// `queue { ... }`: bounds of the outgoing packet queues.
    Queue {
        /// The `queue` keyword.
        keyword: Span,
        /// Statements in order.
        settings: Vec<QueueSetting>,
    },
    /// `stats { ... }`: the statistics endpoint (`address`, `port` and `allow`
    /// statements, read as in a `udp` block).
    Stats {
        /// The `stats` keyword.
        keyword: Span,
        /// Its statements in order.
        settings: Vec<SocketSetting>,
    },
    /// `signing_state PATH;`: where the signing timestamps are saved.
    SigningState {
        /// The `signing_state` keyword.
        keyword: Span,
        /// The path, as written.
        path: Span,
    },
    /// `record { ... }`: recording received frames to `.tlog` files.
    Record {
        /// The `record` keyword.
        keyword: Span,
        /// Statements in order.
        settings: Vec<RecordSetting>,
    },
    /// `dialect PATH;`: MAVLink XML message definitions to load (repeatable).
    Dialect {
        /// The `dialect` keyword.
        keyword: Span,
        /// The path, as written.
        path: Span,
    },
    /// `unknown_messages accept|reject;`: what becomes of frames whose id no dialect
    /// defines.
    UnknownMessages {
        /// The `unknown_messages` keyword.
        keyword: Span,
        /// The value word.
        value: Span,
        /// True for `accept`.
        accept: bool,
    },
    /// `dedup DURATION;`: frames byte-identical to one received within the window are
    /// dropped.
    Dedup {
        /// The `dedup` keyword.
        keyword: Span,
        /// The duration, as written (`500ms`).
        value: Span,
    },
    /// `heartbeat { ... }`: the router's own HEARTBEAT.
    Heartbeat {
        /// The `heartbeat` keyword.
        keyword: Span,
        /// Statements in order.
        settings: Vec<HeartbeatSetting>,
    },
    /// `flight_log { ... }`: the autopilot's flight log, streamed to the router and
    /// written to files.
    FlightLog {
        /// The `flight_log` keyword.
        keyword: Span,
        /// Statements in order.
        settings: Vec<FlightLogSetting>,
    },
    /// `chain NAME { rules }`
    Chain {
        /// The chain name.
        name: Span,
        /// Rules in order.
        rules: Vec<Rule>,
    },
}

/// A statement of a `udp` or `tcp` block; each span covers the value.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SocketSetting {
    /// `port N;`
    Port(Span),
    /// `address IP;`
    Address(IpAst),
    /// `max_bitrate N;`
    MaxBitrate(Span),
    /// `connect HOST:PORT;` or `connect [IPV6]:PORT;`
    Connect {
        /// The whole value.
        span: Span,
        /// The host, without brackets.
        host: Span,
        /// True when the host was written in brackets (an IPv6 address).
        bracketed: bool,
        /// The port digits.
        port: Span,
    },
    /// `max_peers N;`
    MaxPeers(Span),
    /// `allow IP;` or `allow IP/BITS;`
    Allow {
        /// The whole value.
        span: Span,
        /// The address part.
        address: IpAst,
        /// The prefix length digits, when written.
        prefix: Option<Span>,
    },
    /// `signing_key PATH;`
    SigningKey(Span),
    /// `allow_unsigned yes|no;`
    AllowUnsigned(YesNo),
    /// `group NAME;`: the interface is one path to a vehicle with the group's others.
    Group(Span),
    /// `origin ORIGIN;` (websocket blocks): a web page origin whose pages may connect.
    Origin(Span),
}

/// A statement of a `zenoh` block; each span covers the value as written (checked by
/// `super::zenoh_block`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ZenohSetting {
    /// `mode client|peer;`
    Mode(Span),
    /// `connect ENDPOINT;` (repeatable), e.g. `tcp/127.0.0.1:7447`.
    Connect(Span),
    /// `listen ENDPOINT;` (repeatable).
    Listen(Span),
    /// `prefix KEY/EXPR;`: the first chunks of every key.
    Prefix(Span),
    /// `receive addressed|all;`: what the interface subscribes to.
    Receive(Span),
    /// `signing_key PATH;`
    SigningKey(Span),
    /// `allow_unsigned yes|no;`
    AllowUnsigned(YesNo),
}

/// A statement of a `heartbeat` block; each span covers the value.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HeartbeatSetting {
    /// `system N;`
    System(Span),
    /// `component N;`
    Component(Span),
    /// `interval DURATION;`
    Interval(Span),
}

/// A statement of a `flight_log` block; each span covers the value.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FlightLogSetting {
    /// `system N;`: the vehicle whose autopilot's log is streamed.
    System(Span),
    /// `source S.C;`: the router's own address in the stream.
    Source(Span),
    /// `path PATTERN;`: where the logs are written (the extension is added).
    Path(Span),
    /// `mode always|while_armed;`
    Mode(Span),
    /// `protocol auto|dataflash|ulog;`
    Protocol(Span),
    /// `max_files N;`
    MaxFiles(Span),
    /// `min_free_bytes N;`
    MinFreeBytes(Span),
}

/// A written `yes` or `no` after a statement keyword.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct YesNo {
    /// The statement keyword.
    pub keyword: Span,
    /// The value word.
    pub span: Span,
    /// True for `yes`.
    pub yes: bool,
}

/// A written IP address.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct IpAst {
    /// The whole address.
    pub span: Span,
    /// The four octets of an IPv4 address; `None` for an IPv6 address (whose syntax the
    /// parser has checked).
    pub octets: Option<[Span; 4]>,
}

/// A statement of a `queue` block; each span covers the value (a number of bytes).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum QueueSetting {
    /// `link_bytes N;`: what one link's queue may hold.
    LinkBytes(Span),
    /// `total_bytes N;`: what all queues together may hold.
    TotalBytes(Span),
}

/// A statement of a `record` block; spans cover the value.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum RecordSetting {
    /// `path PATTERN;`: where recordings are written, with `%Y %m %d %H %M %S %%`.
    Path(Span),
    /// `max_file_bytes N;`: a file is closed for a new one before it grows beyond this.
    MaxFileBytes(Span),
    /// `max_files N;`: the oldest recordings are removed beyond this many.
    MaxFiles(Span),
    /// `min_free_bytes N;`: the free disk space recording keeps.
    MinFreeBytes(Span),
    /// `only if CONDITION;`: record only frames meeting one of these.
    Only {
        /// The `only` keyword.
        keyword: Span,
        /// The condition, in the syntax of rules (boxed: it is far larger than a span).
        condition: Box<ConditionAst>,
    },
}

/// A statement of a `serial` block; each span covers the value.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SerialSetting {
    /// `device PATH;`
    Device(Span),
    /// `baudrate N;`
    Baudrate(Span),
    /// `flow_control yes|no;`
    FlowControl {
        /// The value word.
        span: Span,
        /// True for `yes`.
        enabled: bool,
    },
    /// `preload S.C;`
    Preload(AddressAst),
    /// `max_bitrate N;`
    MaxBitrate(Span),
    /// `signing_key PATH;`
    SigningKey(Span),
    /// `allow_unsigned yes|no;`
    AllowUnsigned(YesNo),
    /// `group NAME;`
    Group(Span),
}

/// A written MAVLink address `S.C`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AddressAst {
    /// The whole address.
    pub span: Span,
    /// The system number.
    pub system: Span,
    /// The component number.
    pub component: Span,
}

/// A written MAVLink subnet in one of its four forms.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SubnetAst {
    /// The whole subnet text.
    pub span: Span,
    /// The address part.
    pub address: AddressAst,
    /// The mask part.
    pub mask: MaskAst,
}

/// The mask part of a subnet.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MaskAst {
    /// No mask: exact match.
    Exact,
    /// `:S.C` explicit mask.
    Explicit(AddressAst),
    /// `/bits` over the whole 16-bit address.
    Slash(Span),
    /// `\bits` over the component only.
    Backslash(Span),
}

/// A rule of a chain.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Rule {
    /// The action keyword (`accept`, `reject`, `call`, `goto`).
    pub keyword: Span,
    /// What the rule does.
    pub action: ActionAst,
    /// The priority number after `with priority`, sign included.
    pub priority: Option<Span>,
    /// The `with rate N/UNIT` option, if written.
    pub rate: Option<RateAst>,
    /// The `if` part.
    pub condition: Option<ConditionAst>,
}

/// A written `rate N/UNIT` (after `with`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RateAst {
    /// The `rate` keyword.
    pub keyword: Span,
    /// The whole value, `N/UNIT`.
    pub span: Span,
    /// The number before `/`.
    pub count: Span,
    /// The unit after `/`.
    pub unit: Span,
}

/// The action of a rule.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ActionAst {
    /// `accept`
    Accept,
    /// `reject`
    Reject,
    /// `call NAME` (span of the name).
    Call(Span),
    /// `goto NAME` (span of the name).
    Goto(Span),
}

/// `if [signed|unsigned] [TYPE] [from SUBNET] [to SUBNET]`
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ConditionAst {
    /// The `if` keyword.
    pub keyword: Span,
    /// The `signed` or `unsigned` word, and true for `signed`.
    pub signed: Option<(Span, bool)>,
    /// The packet type name.
    pub packet_type: Option<Span>,
    /// The subnet after `from`.
    pub source: Option<SubnetAst>,
    /// The subnet after `to`.
    pub dest: Option<SubnetAst>,
}
