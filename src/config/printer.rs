//! The `--ast` output: the original mavtables' syntax tree format, byte for byte.
//!
//! ```text
//! ===== path =====
//! :001:  chain default
//! :002:  |  accept
//! :002:  |  |  priority 99
//! ```
//! Each node line is `:NNN:  ` (line of the node's own text, zero-padded to three digits),
//! then `|  ` once per nesting level, the node name, and ` <raw text>` for nodes with text.

use super::Span;
use super::ast::*;
use super::lines::LineIndex;
use std::fmt::Write;

/// Renders the header line and the tree of `ast`, read from `path`.
pub fn print_ast(ast: &Ast<'_>, path: &str) -> String {
    let mut p = Printer {
        ast,
        lines: LineIndex::new(ast.src),
        out: format!("===== {path} =====\n"),
    };
    for item in &ast.items {
        p.item(item);
    }
    p.out
}

/// Renders only the tree (no header), as the original's unit tests compare it.
pub fn print_tree(ast: &Ast<'_>) -> String {
    let full = print_ast(ast, "");
    full.split_once('\n')
        .map_or(String::new(), |(_, rest)| rest.to_string())
}

struct Printer<'a, 'b> {
    ast: &'b Ast<'a>,
    lines: LineIndex,
    out: String,
}

impl Printer<'_, '_> {
    fn node(&mut self, depth: usize, at: Span, name: &str, text: Option<Span>) {
        let line = self.lines.line_of(at.start);
        let _ = write!(self.out, ":{line:03}:  ");
        for _ in 0..depth {
            self.out.push_str("|  ");
        }
        self.out.push_str(name);
        if let Some(text) = text {
            self.out.push(' ');
            self.out.push_str(self.ast.text(text));
        }
        self.out.push('\n');
    }

    fn item(&mut self, item: &Item) {
        match item {
            Item::DefaultAction {
                keyword,
                value,
                accept,
            } => self.accept_or_reject(*keyword, "default_action", *value, *accept),
            Item::Udp { keyword, settings } => self.socket(*keyword, "udp", settings),
            Item::Tcp { keyword, settings } => self.socket(*keyword, "tcp", settings),
            Item::WebSocket { keyword, settings } => self.socket(*keyword, "websocket", settings),
            Item::Zenoh { keyword, settings } => {
                self.node(0, *keyword, "zenoh", None);
                for s in settings {
                    let (name, span) = match s {
                        ZenohSetting::Mode(v) => ("mode", *v),
                        ZenohSetting::Connect(v) => ("connect", *v),
                        ZenohSetting::Listen(v) => ("listen", *v),
                        ZenohSetting::Prefix(v) => ("prefix", *v),
                        ZenohSetting::Receive(v) => ("receive", *v),
                        ZenohSetting::SigningKey(v) => ("signing_key", *v),
                        ZenohSetting::AllowUnsigned(v) => ("allow_unsigned", v.span),
                    };
                    self.node(1, span, name, Some(span));
                }
            }
            Item::Serial { keyword, settings } => {
                self.node(0, *keyword, "serial", None);
                for s in settings {
                    let (name, span) = match s {
                        SerialSetting::Device(v) => ("device", *v),
                        SerialSetting::Baudrate(v) => ("baudrate", *v),
                        SerialSetting::FlowControl { span, .. } => ("flow_control", *span),
                        SerialSetting::Preload(a) => ("preload", a.span),
                        SerialSetting::MaxBitrate(v) => ("max_bitrate", *v),
                        SerialSetting::SigningKey(v) => ("signing_key", *v),
                        SerialSetting::AllowUnsigned(v) => ("allow_unsigned", v.span),
                        SerialSetting::Group(v) => ("group", *v),
                    };
                    self.node(1, span, name, Some(span));
                }
            }
            Item::Queue { keyword, settings } => {
                self.node(0, *keyword, "queue", None);
                for s in settings {
                    let (name, span) = match s {
                        QueueSetting::LinkBytes(v) => ("link_bytes", *v),
                        QueueSetting::TotalBytes(v) => ("total_bytes", *v),
                    };
                    self.node(1, span, name, Some(span));
                }
            }
            Item::Stats { keyword, settings } => self.socket(*keyword, "stats", settings),
            Item::SigningState { path, .. } => self.node(0, *path, "signing_state", Some(*path)),
            Item::Dialect { path, .. } => self.node(0, *path, "dialect", Some(*path)),
            Item::UnknownMessages {
                keyword,
                value,
                accept,
            } => self.accept_or_reject(*keyword, "unknown_messages", *value, *accept),
            Item::Record { keyword, settings } => {
                self.node(0, *keyword, "record", None);
                for s in settings {
                    let (name, span) = match s {
                        RecordSetting::Path(v) => ("path", *v),
                        RecordSetting::MaxFileBytes(v) => ("max_file_bytes", *v),
                        RecordSetting::MaxFiles(v) => ("max_files", *v),
                        RecordSetting::MinFreeBytes(v) => ("min_free_bytes", *v),
                        RecordSetting::Only { keyword, condition } => {
                            self.node(1, *keyword, "only", None);
                            self.condition(2, condition);
                            continue;
                        }
                    };
                    self.node(1, span, name, Some(span));
                }
            }
            Item::Dedup { value, .. } => self.node(0, *value, "dedup", Some(*value)),
            Item::Heartbeat { keyword, settings } => {
                self.node(0, *keyword, "heartbeat", None);
                for s in settings {
                    let (name, span) = match s {
                        HeartbeatSetting::System(v) => ("system", *v),
                        HeartbeatSetting::Component(v) => ("component", *v),
                        HeartbeatSetting::Interval(v) => ("interval", *v),
                    };
                    self.node(1, span, name, Some(span));
                }
            }
            Item::FlightLog { keyword, settings } => {
                self.node(0, *keyword, "flight_log", None);
                for s in settings {
                    let (name, span) = match s {
                        FlightLogSetting::System(v) => ("system", *v),
                        FlightLogSetting::Source(v) => ("source", *v),
                        FlightLogSetting::Path(v) => ("path", *v),
                        FlightLogSetting::Mode(v) => ("mode", *v),
                        FlightLogSetting::Protocol(v) => ("protocol", *v),
                        FlightLogSetting::MaxFiles(v) => ("max_files", *v),
                        FlightLogSetting::MinFreeBytes(v) => ("min_free_bytes", *v),
                    };
                    self.node(1, span, name, Some(span));
                }
            }
            Item::Chain { name, rules } => {
                self.node(0, *name, "chain", Some(*name));
                for rule in rules {
                    self.rule(rule);
                }
            }
        }
    }

    /// `NAME accept|reject;`: the statement node, then the value node below it.
    fn accept_or_reject(&mut self, keyword: Span, name: &str, value: Span, accept: bool) {
        self.node(0, keyword, name, None);
        self.node(1, value, if accept { "accept" } else { "reject" }, None);
    }

    /// A `udp`, `tcp` or `websocket` block: the block node, then one node per statement with its raw
    /// value (`connect [fd00::7]:14550`, `allow 192.168.1.0/24`).
    fn socket(&mut self, keyword: Span, name: &str, settings: &[SocketSetting]) {
        self.node(0, keyword, name, None);
        for s in settings {
            let (name, span) = match s {
                SocketSetting::Port(v) => ("port", *v),
                SocketSetting::Address(ip) => ("address", ip.span),
                SocketSetting::MaxBitrate(v) => ("max_bitrate", *v),
                SocketSetting::Connect { span, .. } => ("connect", *span),
                SocketSetting::MaxPeers(v) => ("max_peers", *v),
                SocketSetting::Allow { span, .. } => ("allow", *span),
                // The key file's path, as written: the printer reads no file.
                SocketSetting::SigningKey(v) => ("signing_key", *v),
                SocketSetting::AllowUnsigned(v) => ("allow_unsigned", v.span),
                SocketSetting::Group(v) => ("group", *v),
                SocketSetting::Origin(v) => ("origin", *v),
            };
            self.node(1, span, name, Some(span));
        }
    }

    fn rule(&mut self, rule: &Rule) {
        match rule.action {
            ActionAst::Accept => self.node(1, rule.keyword, "accept", None),
            ActionAst::Reject => self.node(1, rule.keyword, "reject", None),
            ActionAst::Call(target) => self.node(1, target, "call", Some(target)),
            ActionAst::Goto(target) => self.node(1, target, "goto", Some(target)),
        }
        // `with priority` and `with rate` in the order written.
        let mut options: Vec<(Span, &str)> = Vec::new();
        options.extend(rule.priority.map(|p| (p, "priority")));
        options.extend(rule.rate.map(|r| (r.span, "rate")));
        options.sort_by_key(|(span, _)| span.start);
        for (span, name) in options {
            self.node(2, span, name, Some(span));
        }
        if let Some(c) = &rule.condition {
            self.condition(2, c);
        }
    }

    /// A `condition` node at `depth` and its parts below it.
    fn condition(&mut self, depth: usize, c: &ConditionAst) {
        self.node(depth, c.keyword, "condition", None);
        if let Some((at, signed)) = c.signed {
            self.node(
                depth + 1,
                at,
                if signed { "signed" } else { "unsigned" },
                None,
            );
        }
        if let Some(t) = c.packet_type {
            self.node(depth + 1, t, "packet_type", Some(t));
        }
        if let Some(s) = &c.source {
            self.node(depth + 1, s.span, "source", Some(s.span));
        }
        if let Some(d) = &c.dest {
            self.node(depth + 1, d.span, "dest", Some(d.span));
        }
    }
}
