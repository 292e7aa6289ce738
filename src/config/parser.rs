//! Recursive-descent parser: source text to [`Ast`], or the first syntax error.
//!
//! Error texts are the original mavtables' where it had one. Errors point at the
//! offending token; an "expected X" whose token would be on a later line points just
//! after the previous token instead (where the missing thing belongs).

use super::ast::*;
use super::diagnostic::{Diagnostic, Position};
use super::lexer::{Cursor, is_word_char};
use super::{Span, net, suggest};
use std::net::{Ipv4Addr, Ipv6Addr};

const TOP_LEVEL: &[&str] = &[
    "default_action",
    "udp",
    "tcp",
    "websocket",
    "zenoh",
    "serial",
    "queue",
    "chain",
    "signing_state",
    "record",
    "stats",
    "dialect",
    "unknown_messages",
    "dedup",
    "heartbeat",
    "flight_log",
];
const STATS_STATEMENTS: &[&str] = &["address", "port", "allow"];
const UDP_STATEMENTS: &[&str] = &[
    "port",
    "address",
    "max_bitrate",
    "connect",
    "max_peers",
    "allow",
    "signing_key",
    "allow_unsigned",
    "group",
    "origin",
];
const SERIAL_STATEMENTS: &[&str] = &[
    "device",
    "baudrate",
    "flow_control",
    "preload",
    "max_bitrate",
    "signing_key",
    "allow_unsigned",
    "group",
];
const ZENOH_STATEMENTS: &[&str] = &[
    "mode",
    "connect",
    "listen",
    "prefix",
    "receive",
    "signing_key",
    "allow_unsigned",
];
const QUEUE_STATEMENTS: &[&str] = &["link_bytes", "total_bytes"];
const HEARTBEAT_STATEMENTS: &[&str] = &["system", "component", "interval"];
const FLIGHT_LOG_STATEMENTS: &[&str] = &[
    "system",
    "source",
    "path",
    "mode",
    "protocol",
    "max_files",
    "min_free_bytes",
];
const RECORD_STATEMENTS: &[&str] = &[
    "path",
    "max_file_bytes",
    "max_files",
    "min_free_bytes",
    "only",
];
const ACTIONS: &[&str] = &["accept", "reject", "call", "goto"];

const EXPECTED_SEMICOLON: &str = "expected end of statement ';' character";
const INVALID_SUBNET: &str = "expected a valid MAVLink subnet";
const INVALID_ADDRESS: &str = "expected a valid MAVLink address";
const INVALID_CONDITION: &str = "condition is empty or invalid";
const EXPECTED_KEY_PATH: &str = "expected the path of a signing key file";

/// Parses a whole configuration file (syntax only; meaning is checked by
/// `super::semantics`).
pub fn parse(src: &str) -> std::result::Result<Ast<'_>, Diagnostic> {
    let mut p = Parser {
        src,
        c: Cursor::new(src),
    };
    let items = p.file().map_err(|d| name_stray_character(src, d))?;
    Ok(Ast { src, items })
}

/// A syntax error found at a character the language never uses outside comments (one
/// beyond ASCII, or an ASCII control character) names that character, with what was
/// expected as a note: `chain dëfault` is a name with an `ë` in it, not a missing brace.
fn name_stray_character(src: &str, d: Diagnostic) -> Diagnostic {
    let stray = |at: usize| {
        let c = src.get(at..)?.chars().next()?;
        (!c.is_ascii() || (c.is_ascii_control() && !c.is_ascii_whitespace())).then_some((at, c))
    };
    // At the position, or just after the word it points at (`pört` is read as `p`).
    let Some((start, c)) = stray(d.span.start).or_else(|| {
        let after_word = src.get(d.span.start..d.span.end)?.chars().all(is_word_char);
        (d.span.end > d.span.start && after_word)
            .then(|| stray(d.span.end))
            .flatten()
    }) else {
        return d;
    };
    let in_word = src[..start].chars().next_back().is_some_and(is_word_char);
    let what = if in_word {
        "cannot be part of a name: names are ASCII letters, digits and '_'"
    } else {
        "is not part of the language: outside comments it is written in ASCII"
    };
    let span = Span::new(start, start + c.len_utf8());
    let mut named = Diagnostic::new(
        span,
        format!(
            "the character '{}' (U+{:04X}) {what}",
            c.escape_debug(),
            u32::from(c)
        ),
    )
    .with_note(d.message);
    named.notes.extend(d.notes);
    named
}

type Result<T> = std::result::Result<T, Diagnostic>;

struct Parser<'a> {
    src: &'a str,
    c: Cursor<'a>,
}

impl<'a> Parser<'a> {
    fn file(&mut self) -> Result<Vec<Item>> {
        let mut items = Vec::new();
        self.c.skip_padding();
        if self.c.at_end() {
            return Err(Diagnostic::new(
                Span::new(0, 0),
                "expected at least one valid statement or block",
            ));
        }
        while !self.c.at_end() {
            items.push(self.item()?);
            self.c.skip_padding();
        }
        Ok(items)
    }

    fn item(&mut self) -> Result<Item> {
        let (span, word) = match self.c.peek_word() {
            Some((span, word)) if starts_like_name(word) => (span, word),
            _ => return Err(self.stray("a statement or block")),
        };
        match word {
            "default_action" => {
                let (value, accept) = self.accept_or_reject()?;
                Ok(Item::DefaultAction {
                    keyword: span,
                    value,
                    accept,
                })
            }
            "udp" => {
                self.c.word();
                let settings = self.block(span, Self::socket_setting)?;
                Ok(Item::Udp {
                    keyword: span,
                    settings,
                })
            }
            "tcp" => {
                self.c.word();
                let settings = self.block(span, Self::socket_setting)?;
                Ok(Item::Tcp {
                    keyword: span,
                    settings,
                })
            }
            "websocket" => {
                self.c.word();
                let settings = self.block(span, Self::socket_setting)?;
                Ok(Item::WebSocket {
                    keyword: span,
                    settings,
                })
            }
            "zenoh" => {
                self.c.word();
                let settings = self.block(span, Self::zenoh_setting)?;
                Ok(Item::Zenoh {
                    keyword: span,
                    settings,
                })
            }
            "serial" => {
                self.c.word();
                let settings = self.block(span, Self::serial_setting)?;
                Ok(Item::Serial {
                    keyword: span,
                    settings,
                })
            }
            "queue" => {
                self.c.word();
                let settings = self.block(span, Self::queue_setting)?;
                Ok(Item::Queue {
                    keyword: span,
                    settings,
                })
            }
            "stats" => {
                self.c.word();
                let settings = self.block(span, Self::stats_setting)?;
                Ok(Item::Stats {
                    keyword: span,
                    settings,
                })
            }
            "signing_state" => {
                self.c.word();
                let path = self.path("expected the path of the signing state file")?;
                self.semicolon(false)?;
                Ok(Item::SigningState {
                    keyword: span,
                    path,
                })
            }
            "dialect" => {
                self.c.word();
                let path = self.path("expected the path of a MAVLink XML dialect file")?;
                self.semicolon(false)?;
                Ok(Item::Dialect {
                    keyword: span,
                    path,
                })
            }
            "unknown_messages" => {
                let (value, accept) = self.accept_or_reject()?;
                Ok(Item::UnknownMessages {
                    keyword: span,
                    value,
                    accept,
                })
            }
            "record" => {
                self.c.word();
                let settings = self.block(span, Self::record_setting)?;
                Ok(Item::Record {
                    keyword: span,
                    settings,
                })
            }
            "dedup" => {
                self.c.word();
                let value = self.duration("expected a duration, e.g. 500ms or 1s")?;
                self.semicolon(false)?;
                Ok(Item::Dedup {
                    keyword: span,
                    value,
                })
            }
            "flight_log" => {
                self.c.word();
                let settings = self.block(span, Self::flight_log_setting)?;
                Ok(Item::FlightLog {
                    keyword: span,
                    settings,
                })
            }
            "heartbeat" => {
                self.c.word();
                let settings = self.block(span, Self::heartbeat_setting)?;
                Ok(Item::Heartbeat {
                    keyword: span,
                    settings,
                })
            }
            "chain" => {
                self.c.word();
                let name = self.chain_name()?;
                let rules = self.block(span, Self::rule)?;
                Ok(Item::Chain { name, rules })
            }
            _ => Err(unsupported(span, word, TOP_LEVEL)),
        }
    }

    /// The rest of `KEYWORD accept|reject;` (the cursor on the keyword): the value word,
    /// and true for `accept`.
    fn accept_or_reject(&mut self) -> Result<(Span, bool)> {
        self.c.word();
        let at = self.c.expected_at();
        let (value, accept) = match self.c.peek_word() {
            Some((s, "accept")) => (s, true),
            Some((s, "reject")) => (s, false),
            _ => return Err(self.value_error(at, "expected 'accept' or 'reject'")),
        };
        self.c.word();
        self.semicolon(false)?;
        Ok((value, accept))
    }

    /// `{ element* }` where each element is read by `element`.
    fn block<T>(&mut self, keyword: Span, element: fn(&mut Self) -> Result<T>) -> Result<Vec<T>> {
        let at = self.c.expected_at();
        if !self.c.eat('{') {
            return Err(self.value_error(at, "expected opening brace '{'"));
        }
        let mut out = Vec::new();
        loop {
            let at = self.c.expected_at();
            if self.c.eat('}') {
                return Ok(out);
            }
            if self.c.at_end() {
                let line = Position::of(self.src, keyword.start).line;
                return Err(Diagnostic::new(at, "expected closing brace '}'")
                    .with_note(format!("the block starts at line {line}")));
            }
            out.push(element(self)?);
        }
    }

    /// A statement of a `udp`, `tcp` or `websocket` block.
    fn socket_setting(&mut self) -> Result<SocketSetting> {
        let (span, word) = match self.c.peek_word() {
            Some(found) => found,
            None => return Err(self.stray("a statement or '}'")),
        };
        let setting = match word {
            "port" => {
                self.c.word();
                SocketSetting::Port(self.number("expected a valid port number")?)
            }
            "address" => {
                self.c.word();
                SocketSetting::Address(self.ip()?)
            }
            "max_bitrate" => {
                self.c.word();
                SocketSetting::MaxBitrate(self.number("expected a valid bitrate")?)
            }
            "connect" => {
                self.c.word();
                self.connect()?
            }
            "max_peers" => {
                self.c.word();
                SocketSetting::MaxPeers(self.number("expected a valid number of peers")?)
            }
            "allow" => {
                self.c.word();
                self.allow()?
            }
            "signing_key" => {
                self.c.word();
                SocketSetting::SigningKey(self.path(EXPECTED_KEY_PATH)?)
            }
            "allow_unsigned" => {
                self.c.word();
                SocketSetting::AllowUnsigned(self.yes_no(span)?)
            }
            "group" => {
                self.c.word();
                SocketSetting::Group(self.group_name()?)
            }
            "origin" => {
                self.c.word();
                SocketSetting::Origin(
                    self.path("expected a web origin, e.g. http://localhost:8080")?,
                )
            }
            _ => return Err(unsupported(span, word, UDP_STATEMENTS)),
        };
        self.semicolon(false)?;
        Ok(setting)
    }

    /// A statement of a `zenoh` block: its value is read as written, up to whitespace,
    /// `;`, `#` or a brace (`super::zenoh_block` checks it).
    fn zenoh_setting(&mut self) -> Result<ZenohSetting> {
        let (span, word) = match self.c.peek_word() {
            Some(found) => found,
            None => return Err(self.stray("a statement or '}'")),
        };
        let expected = match word {
            "mode" => "expected 'client' or 'peer'",
            "connect" | "listen" => "expected a Zenoh endpoint, e.g. tcp/127.0.0.1:7447",
            "prefix" => "expected a key prefix, e.g. fleet/alpha",
            "receive" => "expected 'addressed' or 'all'",
            "signing_key" => EXPECTED_KEY_PATH,
            "allow_unsigned" => "",
            _ => return Err(unsupported(span, word, ZENOH_STATEMENTS)),
        };
        self.c.word();
        if word == "allow_unsigned" {
            let value = self.yes_no(span)?;
            self.semicolon(false)?;
            return Ok(ZenohSetting::AllowUnsigned(value));
        }
        let value = self.path(expected)?;
        self.semicolon(false)?;
        Ok(match word {
            "mode" => ZenohSetting::Mode(value),
            "connect" => ZenohSetting::Connect(value),
            "listen" => ZenohSetting::Listen(value),
            "prefix" => ZenohSetting::Prefix(value),
            "receive" => ZenohSetting::Receive(value),
            _ => ZenohSetting::SigningKey(value),
        })
    }

    /// `HOST:PORT` or `[IPV6]:PORT`: the value runs to whitespace, `;`, `#` or a brace.
    fn connect(&mut self) -> Result<SocketSetting> {
        let at = self.c.expected_at();
        let span = self
            .c
            .take_while(|c| !c.is_whitespace() && !matches!(c, ';' | '#' | '{' | '}'));
        if span.is_empty() {
            return Err(Diagnostic::new(at, "expected a host and port")
                .with_note("write HOST:PORT, e.g. 192.168.1.50:14550 or [fd00::7]:14550"));
        }
        let text = self.c.text(span);
        let at = |r: std::ops::Range<usize>| Span::new(span.start + r.start, span.start + r.end);
        match net::split_host_port(text) {
            Ok(hp) => Ok(SocketSetting::Connect {
                span,
                host: at(hp.host),
                bracketed: hp.bracketed,
                port: at(hp.port),
            }),
            Err(e) => {
                let mut d = Diagnostic::new(at(e.at), e.message);
                if let Some(note) = e.note {
                    d = d.with_note(note);
                }
                Err(d)
            }
        }
    }

    /// `IP` or `IP/BITS`.
    fn allow(&mut self) -> Result<SocketSetting> {
        let address = self.ip()?;
        let prefix = if self.c.eat('/') {
            let bits = self.c.digits();
            if bits.is_empty() {
                return Err(Diagnostic::new(
                    self.c.char_span(),
                    "expected a prefix length (a number of bits) after '/'",
                ));
            }
            Some(bits)
        } else {
            None
        };
        let end = prefix.map_or(address.span.end, |p| p.end);
        Ok(SocketSetting::Allow {
            span: Span::new(address.span.start, end),
            address,
            prefix,
        })
    }

    fn serial_setting(&mut self) -> Result<SerialSetting> {
        let (span, word) = match self.c.peek_word() {
            Some(found) => found,
            None => return Err(self.stray("a statement or '}'")),
        };
        let setting = match word {
            "device" => {
                self.c.word();
                SerialSetting::Device(self.path("expected a valid serial port device name")?)
            }
            "baudrate" => {
                self.c.word();
                SerialSetting::Baudrate(self.number("expected a valid baud rate")?)
            }
            "flow_control" => {
                self.c.word();
                let value = self.yes_no(span)?;
                SerialSetting::FlowControl {
                    span: value.span,
                    enabled: value.yes,
                }
            }
            "preload" => {
                self.c.word();
                self.c.skip_padding();
                SerialSetting::Preload(self.address(INVALID_ADDRESS)?)
            }
            "max_bitrate" => {
                self.c.word();
                SerialSetting::MaxBitrate(self.number("expected a valid bitrate")?)
            }
            "signing_key" => {
                self.c.word();
                SerialSetting::SigningKey(self.path(EXPECTED_KEY_PATH)?)
            }
            "allow_unsigned" => {
                self.c.word();
                SerialSetting::AllowUnsigned(self.yes_no(span)?)
            }
            "group" => {
                self.c.word();
                SerialSetting::Group(self.group_name()?)
            }
            _ => return Err(unsupported(span, word, SERIAL_STATEMENTS)),
        };
        self.semicolon(false)?;
        Ok(setting)
    }

    /// A path (of a device or file), written as is: it runs to whitespace, `;`, `#` or a
    /// brace.
    fn path(&mut self, message: &str) -> Result<Span> {
        let at = self.c.expected_at();
        let path = self
            .c
            .take_while(|c| !c.is_whitespace() && !matches!(c, ';' | '#' | '{' | '}'));
        if path.is_empty() {
            return Err(self.value_error(at, message));
        }
        Ok(path)
    }

    /// `yes` or `no` after the statement keyword at `keyword`.
    fn yes_no(&mut self, keyword: Span) -> Result<YesNo> {
        let at = self.c.expected_at();
        let yes = match self.c.peek_word() {
            Some((_, "yes")) => true,
            Some((_, "no")) => false,
            _ => return Err(self.value_error(at, "expected 'yes' or 'no'")),
        };
        let (span, _) = self.c.word().unwrap_or((at, ""));
        Ok(YesNo { keyword, span, yes })
    }

    /// A statement of a `stats` block: `address IP;`, `port N;` or `allow RANGE;`, read
    /// as in a `udp` block; the others of that block are not statements here.
    fn stats_setting(&mut self) -> Result<SocketSetting> {
        match self.c.peek_word() {
            Some((span, word)) if !STATS_STATEMENTS.contains(&word) => {
                Err(unsupported(span, word, STATS_STATEMENTS))
            }
            _ => self.socket_setting(),
        }
    }

    fn queue_setting(&mut self) -> Result<QueueSetting> {
        const MESSAGE: &str = "expected a valid number of bytes";
        let (span, word) = match self.c.peek_word() {
            Some(found) => found,
            None => return Err(self.stray("a statement or '}'")),
        };
        let setting = match word {
            "link_bytes" => {
                self.c.word();
                QueueSetting::LinkBytes(self.bytes(MESSAGE)?)
            }
            "total_bytes" => {
                self.c.word();
                QueueSetting::TotalBytes(self.bytes(MESSAGE)?)
            }
            _ => return Err(unsupported(span, word, QUEUE_STATEMENTS)),
        };
        self.semicolon(false)?;
        Ok(setting)
    }

    /// A statement of a `heartbeat` block.
    fn heartbeat_setting(&mut self) -> Result<HeartbeatSetting> {
        let (span, word) = match self.c.peek_word() {
            Some(found) => found,
            None => return Err(self.stray("a statement or '}'")),
        };
        let setting = match word {
            "system" => {
                self.c.word();
                HeartbeatSetting::System(self.number("expected a valid system id")?)
            }
            "component" => {
                self.c.word();
                HeartbeatSetting::Component(self.number("expected a valid component id")?)
            }
            "interval" => {
                self.c.word();
                HeartbeatSetting::Interval(self.duration("expected a duration, e.g. 1s or 500ms")?)
            }
            _ => return Err(unsupported(span, word, HEARTBEAT_STATEMENTS)),
        };
        self.semicolon(false)?;
        Ok(setting)
    }

    /// A statement of a `flight_log` block; the values are checked by the semantics.
    fn flight_log_setting(&mut self) -> Result<FlightLogSetting> {
        const BYTES: &str = "expected a valid number of bytes";
        let (span, word) = match self.c.peek_word() {
            Some(found) => found,
            None => return Err(self.stray("a statement or '}'")),
        };
        let setting = match word {
            "system" => {
                self.c.word();
                FlightLogSetting::System(self.number("expected a valid system id")?)
            }
            "source" => {
                self.c.word();
                FlightLogSetting::Source(self.path("expected the router's address, e.g. 245.190")?)
            }
            "path" => {
                self.c.word();
                FlightLogSetting::Path(self.path("expected the path of the flight logs")?)
            }
            "mode" => {
                self.c.word();
                FlightLogSetting::Mode(self.path("expected 'always' or 'while_armed'")?)
            }
            "protocol" => {
                self.c.word();
                FlightLogSetting::Protocol(self.path("expected 'auto', 'dataflash' or 'ulog'")?)
            }
            "max_files" => {
                self.c.word();
                FlightLogSetting::MaxFiles(self.number("expected a valid number of files")?)
            }
            "min_free_bytes" => {
                self.c.word();
                FlightLogSetting::MinFreeBytes(self.bytes(BYTES)?)
            }
            _ => return Err(unsupported(span, word, FLIGHT_LOG_STATEMENTS)),
        };
        self.semicolon(false)?;
        Ok(setting)
    }

    /// A duration: digits then a unit, one word (`500ms`, `1s`); the unit is checked by
    /// the semantics.
    fn duration(&mut self, message: &str) -> Result<Span> {
        let at = self.c.expected_at();
        match self.c.peek_word() {
            Some((span, w)) if w.starts_with(|c: char| c.is_ascii_digit()) => {
                self.c.word();
                Ok(span)
            }
            _ => Err(self
                .value_error(at, message)
                .with_note("write a number and a unit: ms, s or min")),
        }
    }

    /// The name after `group`.
    fn group_name(&mut self) -> Result<Span> {
        let at = self.c.expected_at();
        match self.c.peek_word() {
            Some((span, w)) if starts_like_name(w) => {
                self.c.word();
                Ok(span)
            }
            _ => Err(self.value_error(at, "expected a group name")),
        }
    }

    /// A statement of a `record` block.
    fn record_setting(&mut self) -> Result<RecordSetting> {
        const BYTES: &str = "expected a valid number of bytes";
        let (span, word) = match self.c.peek_word() {
            Some(found) => found,
            None => return Err(self.stray("a statement or '}'")),
        };
        let setting =
            match word {
                "path" => {
                    self.c.word();
                    RecordSetting::Path(self.path("expected the path of the recordings")?)
                }
                "max_file_bytes" => {
                    self.c.word();
                    RecordSetting::MaxFileBytes(self.bytes(BYTES)?)
                }
                "max_files" => {
                    self.c.word();
                    RecordSetting::MaxFiles(self.number("expected a valid number of files")?)
                }
                "min_free_bytes" => {
                    self.c.word();
                    RecordSetting::MinFreeBytes(self.bytes(BYTES)?)
                }
                "only" => {
                    self.c.word();
                    let at = self.c.expected_at();
                    let Some(kw) = self.c.eat_keyword("if") else {
                        return Err(self.value_error(at, "expected 'if' after 'only'").with_note(
                        "write: only if [signed|unsigned] [TYPE] [from SUBNET] [to SUBNET];",
                    ));
                    };
                    RecordSetting::Only {
                        keyword: span,
                        condition: Box::new(self.condition(kw)?),
                    }
                }
                _ => return Err(unsupported(span, word, RECORD_STATEMENTS)),
            };
        self.semicolon(false)?;
        Ok(setting)
    }

    fn rule(&mut self) -> Result<Rule> {
        let (keyword, word) = match self.c.peek_word() {
            Some((span, w)) if ACTIONS.contains(&w) => (span, w),
            Some((span, w)) => {
                let mut d = Diagnostic::new(span, "expected a valid rule");
                if let Some(note) = suggest::did_you_mean(w, ACTIONS.iter().copied()) {
                    d = d.with_note(note);
                }
                return Err(d);
            }
            None => return Err(Diagnostic::new(self.c.char_span(), "expected a valid rule")),
        };
        self.c.word();
        let action = match word {
            "accept" => ActionAst::Accept,
            "reject" => ActionAst::Reject,
            "call" => ActionAst::Call(self.chain_name()?),
            _ => ActionAst::Goto(self.chain_name()?),
        };
        self.c.skip_padding();
        let (priority, rate) = self.rule_options()?;
        self.c.skip_padding();
        let condition = match self.c.eat_keyword("if") {
            Some(kw) => Some(self.condition(kw)?),
            None => None,
        };
        self.semicolon(true)?;
        Ok(Rule {
            keyword,
            action,
            priority,
            rate,
            condition,
        })
    }

    /// The `with priority N` and `with rate N/UNIT` options of a rule, each at most once,
    /// in either order.
    fn rule_options(&mut self) -> Result<(Option<Span>, Option<RateAst>)> {
        let (mut priority, mut rate) = (None, None);
        while self.c.eat_keyword("with").is_some() {
            self.c.skip_padding();
            match self.c.peek_word() {
                Some((kw, "rate")) => {
                    if rate.is_some() {
                        return Err(Diagnostic::new(kw, "a rule takes one rate"));
                    }
                    self.c.word();
                    rate = Some(self.rate(kw)?);
                }
                Some((kw, "priority")) if priority.is_some() => {
                    return Err(Diagnostic::new(kw, "a rule takes one priority"));
                }
                _ => priority = Some(self.priority()?),
            }
            self.c.skip_padding();
        }
        Ok((priority, rate))
    }

    /// `N/UNIT` after the `rate` keyword at `keyword` (checked by the semantics).
    fn rate(&mut self, keyword: Span) -> Result<RateAst> {
        const NOTE: &str = "write a rate as packets per unit: 2/s, 0.5/s, 10/min or 1/h";
        self.c.skip_padding();
        let at = self.c.expected_at();
        let start = self.c.pos();
        let count = self.c.take_while(|c| c.is_ascii_digit() || c == '.');
        if count.is_empty() || !self.c.eat('/') {
            let span = if count.is_empty() {
                at
            } else {
                self.c.char_span()
            };
            return Err(self.value_error(span, "expected a rate").with_note(NOTE));
        }
        let unit = self.c.take_while(|c| c.is_ascii_alphanumeric() || c == '_');
        if unit.is_empty() {
            return Err(Diagnostic::new(self.c.char_span(), "expected a rate unit").with_note(NOTE));
        }
        Ok(RateAst {
            keyword,
            span: Span::new(start, unit.end),
            count,
            unit,
        })
    }

    fn priority(&mut self) -> Result<Span> {
        let at = self.c.expected_at();
        if self.c.eat_keyword("priority").is_none() {
            return Err(self
                .value_error(
                    at,
                    "'with' keyword must be followed by the 'priority' keyword",
                )
                .with_note("or by 'rate': accept with rate 2/s if ATTITUDE;"));
        }
        let at = self.c.expected_at();
        let start = self.c.pos();
        let _ = self.c.eat('+') || self.c.eat('-');
        let digits = self.c.digits();
        if digits.is_empty() || self.c.peek().is_some_and(is_word_char) {
            return Err(self.value_error(at, "expected priority level"));
        }
        Ok(Span::new(start, digits.end))
    }

    fn condition(&mut self, keyword: Span) -> Result<ConditionAst> {
        let mut cond = ConditionAst {
            keyword,
            signed: None,
            packet_type: None,
            source: None,
            dest: None,
        };
        let at = self.c.expected_at();
        // `signed`/`unsigned` cannot be message names, which are upper case.
        if let Some(span) = self.c.eat_keyword("signed") {
            cond.signed = Some((span, true));
        } else if let Some(span) = self.c.eat_keyword("unsigned") {
            cond.signed = Some((span, false));
        }
        self.c.skip_padding();
        if let Some((span, word)) = self.c.peek_word()
            && word != "from"
            && word != "to"
        {
            if !word
                .chars()
                .all(|c| c.is_ascii_uppercase() || c.is_ascii_digit() || c == '_')
            {
                let mut d = Diagnostic::new(span, INVALID_CONDITION);
                let upper = word.to_ascii_uppercase();
                if crate::dialect::by_name(&upper).is_some() {
                    d = d.with_note(format!(
                        "message names are written in upper case: '{upper}'"
                    ));
                }
                return Err(d);
            }
            self.c.word();
            cond.packet_type = Some(span);
        }
        self.c.skip_padding();
        if self.c.eat_keyword("from").is_some() {
            self.c.skip_padding();
            cond.source = Some(self.subnet()?);
        }
        self.c.skip_padding();
        if self.c.eat_keyword("to").is_some() {
            self.c.skip_padding();
            cond.dest = Some(self.subnet()?);
        }
        if cond.signed.is_none()
            && cond.packet_type.is_none()
            && cond.source.is_none()
            && cond.dest.is_none()
        {
            return Err(self.value_error(at, INVALID_CONDITION));
        }
        Ok(cond)
    }

    /// `S.C`, `S.C:S.C`, `S.C/bits` or `S.C\bits`; the cursor is on the first digit.
    fn subnet(&mut self) -> Result<SubnetAst> {
        let start = self.c.pos();
        let address = self.address(INVALID_SUBNET)?;
        let mask = if self.c.eat(':') {
            MaskAst::Explicit(self.address(INVALID_ADDRESS)?)
        } else if self.c.eat('/') {
            MaskAst::Slash(self.mask_bits()?)
        } else if self.c.eat('\\') {
            MaskAst::Backslash(self.mask_bits()?)
        } else {
            MaskAst::Exact
        };
        let end = self.c.pos();
        if self.c.peek().is_some_and(is_word_char) {
            return Err(Diagnostic::new(self.c.char_span(), INVALID_SUBNET));
        }
        Ok(SubnetAst {
            span: Span::new(start, end),
            address,
            mask,
        })
    }

    fn mask_bits(&mut self) -> Result<Span> {
        let bits = self.c.digits();
        if bits.is_empty() {
            return Err(Diagnostic::new(self.c.char_span(), INVALID_SUBNET));
        }
        Ok(bits)
    }

    /// `S.C` at the cursor (no padding inside).
    fn address(&mut self, message: &str) -> Result<AddressAst> {
        let start = self.c.pos();
        let system = self.c.digits();
        if system.is_empty() {
            let at = if self.c.at_end() || self.c.peek() == Some('\n') {
                self.c.expected_at()
            } else {
                self.c.char_span()
            };
            return Err(self.value_error(at, message));
        }
        if !self.c.eat('.') {
            return Err(Diagnostic::new(self.c.char_span(), message));
        }
        let component = self.c.digits();
        if component.is_empty() {
            return Err(Diagnostic::new(self.c.char_span(), message));
        }
        Ok(AddressAst {
            span: Span::new(start, component.end),
            system,
            component,
        })
    }

    /// An IPv4 address (`a.b.c.d`, octet ranges checked later) or an IPv6 address (any
    /// run of hexadecimal digits, `:` and `.` holding a `:`, checked here).
    fn ip(&mut self) -> Result<IpAst> {
        const MESSAGE: &str = "expected a valid IP address";
        let at = self.c.expected_at();
        let start = self.c.pos();
        let rest = &self.src[start..];
        let len = rest
            .find(|c: char| !(c.is_ascii_hexdigit() || c == ':' || c == '.'))
            .unwrap_or(rest.len());
        let run = &rest[..len];
        if run.contains(':') {
            let span = Span::new(start, start + len);
            if run.parse::<Ipv6Addr>().is_err() {
                let note = match run.rsplit_once(':') {
                    Some((ip, _)) if ip.parse::<Ipv4Addr>().is_ok() => {
                        "an address is written without a port here"
                    }
                    _ => {
                        "an IPv6 address is hexadecimal groups separated by ':', e.g. fd00::7 or ::"
                    }
                };
                return Err(Diagnostic::new(span, MESSAGE).with_note(note));
            }
            self.c
                .take_while(|c| c.is_ascii_hexdigit() || c == ':' || c == '.');
            return Ok(IpAst { span, octets: None });
        }
        let mut octets = [Span::new(0, 0); 4];
        for (i, octet) in octets.iter_mut().enumerate() {
            if i > 0 && !self.c.eat('.') {
                return Err(Diagnostic::new(self.c.char_span(), MESSAGE));
            }
            *octet = self.c.digits();
            if octet.is_empty() {
                return Err(if i == 0 {
                    self.value_error(at, MESSAGE)
                } else {
                    Diagnostic::new(self.c.char_span(), MESSAGE)
                });
            }
        }
        Ok(IpAst {
            span: Span::new(start, octets[3].end),
            octets: Some(octets),
        })
    }

    /// A number of bytes: a whole word of digits, optionally ending in `K`, `M`, `G` or
    /// `T` (the semantics read it).
    fn bytes(&mut self, message: &str) -> Result<Span> {
        let at = self.c.expected_at();
        match self.c.peek_word() {
            Some((span, w)) if super::values::looks_like_bytes(w) => {
                self.c.word();
                Ok(span)
            }
            _ => Err(self.value_error(at, message)),
        }
    }

    /// An unsigned number written as a whole word of digits.
    fn number(&mut self, message: &str) -> Result<Span> {
        let at = self.c.expected_at();
        match self.c.peek_word() {
            Some((span, w)) if w.bytes().all(|b| b.is_ascii_digit()) => {
                self.c.word();
                Ok(span)
            }
            _ => Err(self.value_error(at, message)),
        }
    }

    fn chain_name(&mut self) -> Result<Span> {
        let at = self.c.expected_at();
        match self.c.peek_word() {
            Some((span, w)) if starts_like_name(w) => {
                self.c.word();
                Ok(span)
            }
            _ => Err(self.value_error(at, "expected a valid chain name")),
        }
    }

    fn semicolon(&mut self, in_rule: bool) -> Result<()> {
        let at = self.c.expected_at();
        if self.c.eat(';') {
            return Ok(());
        }
        let mut d = self.value_error(at, EXPECTED_SEMICOLON);
        if in_rule
            && let Some((_, w)) = self.c.peek_word()
            && matches!(w, "with" | "if" | "from" | "to" | "signed" | "unsigned")
        {
            d = d.with_note(
                "a rule is written: ACTION [with priority N] [if [signed|unsigned] [TYPE] [from SUBNET] [to SUBNET]];",
            );
        }
        Err(d)
    }

    /// An error at `at`, widened to the whole word when `at` is the start of one.
    fn value_error(&self, at: Span, message: &str) -> Diagnostic {
        let mut span = at;
        if !at.is_empty()
            && at.start == self.c.pos()
            && let Some((word, _)) = self.c.peek_word()
        {
            span = word;
        }
        Diagnostic::new(span, message)
    }

    /// Text that cannot start anything here.
    fn stray(&self, expected: &str) -> Diagnostic {
        let (span, shown) = match self.c.peek_word() {
            Some((span, w)) => (span, w.to_string()),
            None => {
                let span = self.c.char_span();
                let shown = self
                    .c
                    .peek()
                    .map_or(String::new(), |c| c.escape_debug().to_string());
                (span, shown)
            }
        };
        Diagnostic::new(span, format!("expected {expected}, found '{shown}'"))
    }
}

/// Names (chain names, statement keywords) start with a letter or `_`.
fn starts_like_name(word: &str) -> bool {
    word.chars()
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
}

fn unsupported(span: Span, word: &str, candidates: &[&str]) -> Diagnostic {
    let mut d = Diagnostic::new(span, "unsupported statement");
    if let Some(note) = suggest::did_you_mean(word, candidates.iter().copied()) {
        d = d.with_note(note);
    } else {
        let homes: Vec<&str> = [
            ("udp", UDP_STATEMENTS),
            ("tcp", UDP_STATEMENTS),
            ("serial", SERIAL_STATEMENTS),
            ("zenoh", ZENOH_STATEMENTS),
            ("queue", QUEUE_STATEMENTS),
            ("record", RECORD_STATEMENTS),
            ("heartbeat", HEARTBEAT_STATEMENTS),
            ("flight_log", FLIGHT_LOG_STATEMENTS),
        ]
        .into_iter()
        .filter(|(_, list)| list.contains(&word) && candidates != *list)
        .map(|(block, _)| block)
        .collect();
        if let Some(first) = homes.first() {
            let others: String = homes[1..].iter().map(|b| format!(" or '{b}'")).collect();
            d = d.with_note(format!("'{word}' belongs in a '{first}'{others} block"));
        }
    }
    d
}
