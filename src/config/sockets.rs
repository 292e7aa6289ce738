//! The meaning of a `udp`, `tcp` or `websocket` block: values checked and defaults filled in, and the
//! rules of clients (a block with `connect`) against servers. Every error found is
//! collected, in statement order.

use super::Span;
use super::ast::{Ast, IpAst, SocketSetting};
use super::diagnostic::Diagnostic;
use super::model::*;
use super::net::{self, TextError};
use super::values::{interface_signing, ranged};
use std::net::{IpAddr, Ipv4Addr, Ipv6Addr};

/// Which block is being checked.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Kind {
    /// A `udp` block.
    Udp,
    /// A `tcp` block.
    Tcp,
    /// A `websocket` block (a server only).
    WebSocket,
}

/// Checks the statements of one `udp`, `tcp` or `websocket` block; `None` after reporting its errors.
pub(crate) fn check(
    ast: &Ast<'_>,
    kind: Kind,
    settings: &[SocketSetting],
    errors: &mut Vec<Diagnostic>,
) -> Option<Interface> {
    let mut cx = Block {
        ast,
        errors,
        ok: true,
    };
    let mut port = None;
    let mut address = None;
    let mut max_bitrate = None;
    let mut connect: Option<(Remote, Span)> = None;
    let mut connect_at: Option<Span> = None;
    let mut max_peers = None;
    let mut allow = Vec::new();
    let mut first_allow = None;
    let mut key_file = None;
    let mut allow_unsigned = Vec::new();
    let mut origins = Vec::new();
    for s in settings {
        match s {
            SocketSetting::Port(v) => {
                port = cx
                    .number(*v, 0, 65535, "port number")
                    .map(|p| (p as u16, *v));
            }
            SocketSetting::Address(ip) => address = cx.ip(ip).map(|a| (a, ip.span)),
            SocketSetting::MaxBitrate(v) => {
                max_bitrate = cx
                    .number(*v, 0, u64::MAX, "bitrate")
                    .map(|b| (b > 0).then_some(b));
            }
            SocketSetting::Connect {
                span,
                host,
                bracketed,
                port,
            } => {
                if kind == Kind::WebSocket {
                    cx.error(
                        Diagnostic::new(*span, "a websocket block is a server only")
                            .with_note("browsers connect to it; leave out 'connect'"),
                    );
                    continue;
                }
                if let Some(first) = connect_at {
                    let line = super::Position::of(ast.src, first.start).line;
                    cx.error(
                        Diagnostic::new(*span, "a block connects to one peer only")
                            .with_note(format!(
                                "this block already connects on line {line}; write another block for another peer"
                            )),
                    );
                    continue;
                }
                connect_at = Some(*span);
                let host_value = cx.located(*host, net::host(ast.text(*host), *bracketed));
                let port_value = cx.located(*port, net::port(ast.text(*port), 1));
                if let (Some(host), Some(port)) = (host_value, port_value) {
                    connect = Some((Remote { host, port }, *span));
                }
            }
            SocketSetting::MaxPeers(v) => {
                max_peers = cx
                    .number(*v, 1, 65535, "max_peers")
                    .map(|n| (n as usize, *v));
            }
            SocketSetting::Allow {
                span,
                address,
                prefix,
            } => {
                first_allow.get_or_insert(*span);
                if let Some(range) = cx.range(address, *prefix) {
                    allow.push(range);
                }
            }
            SocketSetting::SigningKey(v) => key_file = Some(*v),
            SocketSetting::AllowUnsigned(v) => allow_unsigned.push(*v),
            SocketSetting::Group(_) => {} // see `super::paths::group`
            SocketSetting::Origin(v) => {
                if kind != Kind::WebSocket {
                    cx.error(
                        Diagnostic::new(*v, "'origin' applies to websocket blocks only").with_note(
                            "web pages connect to a websocket block; other peers send no origin",
                        ),
                    );
                } else if let Some(origin) = cx.located(*v, web_origin(ast.text(*v))) {
                    origins.push(origin);
                }
            }
        }
    }
    let signing = match interface_signing(ast, key_file, &allow_unsigned) {
        Ok(signing) => signing,
        Err(d) => {
            cx.error(d);
            None
        }
    };
    let block = match kind {
        Kind::Udp => "udp",
        Kind::Tcp => "tcp",
        Kind::WebSocket => "websocket",
    };
    if let Some((remote, _)) = &connect {
        if kind == Kind::Tcp
            && let Some((_, at)) = port
        {
            cx.error(
                Diagnostic::new(at, "a TCP client has no local port to set")
                    .with_note("leave out 'port', or leave out 'connect' to listen on this port"),
            );
        }
        for (name, at) in [
            ("max_peers", max_peers.map(|(_, at)| at)),
            ("allow", first_allow),
        ] {
            if let Some(at) = at {
                cx.error(
                    Diagnostic::new(at, format!("'{name}' applies to server blocks only"))
                        .with_note(format!(
                            "this {block} block is a client of {remote} (it has 'connect'); a client has one peer"
                        )),
                );
            }
        }
        if let (Some((local, at)), Host::Ip(peer)) = (address, &remote.host)
            && local.is_ipv4() != peer.is_ipv4()
        {
            cx.error(
                Diagnostic::new(
                    at,
                    format!(
                        "address {local} is {}, but the block connects to the {} address {peer}",
                        family(local),
                        family(*peer)
                    ),
                )
                .with_note("a socket talks to peers of its own family; leave out 'address' or use one of that family"),
            );
        }
    }
    if !cx.ok {
        return None;
    }
    let address = address.map(|(a, _)| a);
    let max_bitrate = max_bitrate.flatten();
    let peers = PeerLimits {
        max_peers: max_peers.map_or(DEFAULT_MAX_PEERS, |(n, _)| n),
        allow,
    };
    let connect = connect.map(|(r, _)| r);
    Some(match kind {
        Kind::Udp => Interface::Udp(UdpInterface {
            // A client's local port is any free one unless given.
            port: port.map_or(if connect.is_some() { 0 } else { 14500 }, |(p, _)| p),
            address,
            max_bitrate,
            connect,
            peers,
            signing,
        }),
        Kind::Tcp => Interface::Tcp(TcpInterface {
            port: port.map_or(TcpInterface::DEFAULT_PORT, |(p, _)| p),
            address,
            max_bitrate,
            connect,
            peers,
            signing,
        }),
        Kind::WebSocket => Interface::WebSocket(WebSocketInterface {
            port: port.map_or(WebSocketInterface::DEFAULT_PORT, |(p, _)| p),
            address,
            max_bitrate,
            peers,
            signing,
            origins,
        }),
    })
}

/// A web origin as browsers send it in the `Origin` header: `http://` or `https://`, a
/// host (a name, an IPv4 address or a bracketed IPv6 one) and an optional port, no path.
/// Returned in lower case (browsers send scheme and host so).
fn web_origin(text: &str) -> Result<String, TextError> {
    let error = |at: std::ops::Range<usize>, message: &str, note: &str| TextError {
        at,
        message: message.to_string(),
        note: Some(note.to_string()),
    };
    let form = "write SCHEME://HOST or SCHEME://HOST:PORT, e.g. http://localhost:8080";
    let lower = text.to_ascii_lowercase();
    let Some(rest) = lower
        .strip_prefix("http://")
        .or_else(|| lower.strip_prefix("https://"))
    else {
        return Err(error(
            0..text.len(),
            "expected an origin starting with http:// or https://",
            form,
        ));
    };
    let host_at = text.len() - rest.len();
    if let Some(slash) = rest.find(['/', '?', '#', '@']) {
        return Err(error(
            host_at + slash..text.len(),
            "an origin has no path, query or user",
            form,
        ));
    }
    let (host, port) = match rest.rfind(':') {
        Some(colon) if !rest[colon..].contains(']') => (&rest[..colon], Some(&rest[colon + 1..])),
        _ => (rest, None),
    };
    let host_ok = match host.strip_prefix('[').and_then(|h| h.strip_suffix(']')) {
        Some(v6) => v6.parse::<Ipv6Addr>().is_ok(),
        None => {
            !host.is_empty()
                && host
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '.' | '_'))
        }
    };
    if !host_ok {
        return Err(error(
            host_at..host_at + host.len(),
            "expected a host name or address",
            form,
        ));
    }
    if let Some(port) = port {
        let at = host_at + host.len() + 1;
        if !matches!(port.parse::<u16>(), Ok(p) if p > 0) || port.starts_with('+') {
            return Err(error(
                at..text.len(),
                "expected a port number (1 - 65535)",
                form,
            ));
        }
    }
    Ok(lower)
}

fn family(ip: IpAddr) -> &'static str {
    if ip.is_ipv4() { "IPv4" } else { "IPv6" }
}

struct Block<'a, 'b, 'e> {
    ast: &'b Ast<'a>,
    errors: &'e mut Vec<Diagnostic>,
    ok: bool,
}

impl Block<'_, '_, '_> {
    fn error(&mut self, d: Diagnostic) {
        self.ok = false;
        self.errors.push(d);
    }

    /// The value of `result`, or its error placed inside `span` (the text it read).
    fn located<T>(&mut self, span: Span, result: Result<T, TextError>) -> Option<T> {
        match result {
            Ok(v) => Some(v),
            Err(e) => {
                let at = Span::new(span.start + e.at.start, span.start + e.at.end);
                let mut d = Diagnostic::new(at, e.message);
                if let Some(note) = e.note {
                    d = d.with_note(note);
                }
                self.error(d);
                None
            }
        }
    }

    /// A decimal number within `min..=max`, or an error naming `what`.
    fn number(&mut self, span: Span, min: u64, max: u64, what: &str) -> Option<u64> {
        let text = self.ast.text(span);
        ranged(text, min, max, what)
            .map_err(|message| self.error(Diagnostic::new(span, message)))
            .ok()
    }

    /// A written address: IPv4 octets are range-checked (every bad one reported); IPv6
    /// syntax was checked by the parser.
    fn ip(&mut self, ip: &IpAst) -> Option<IpAddr> {
        let Some(octets) = ip.octets else {
            let text = self.ast.text(ip.span);
            return match text.parse::<Ipv6Addr>() {
                Ok(v6) => Some(IpAddr::V6(v6)),
                Err(_) => {
                    self.error(Diagnostic::new(ip.span, "expected a valid IP address"));
                    None
                }
            };
        };
        let mut bytes = [0u8; 4];
        let mut ok = true;
        for (b, span) in bytes.iter_mut().zip(octets) {
            let text = self.ast.text(span);
            match text.parse::<u8>() {
                Ok(v) => *b = v,
                Err(_) => {
                    ok = false;
                    self.error(Diagnostic::new(
                        span,
                        format!(
                            "Address octet ({text}) is outside of the allowed range (0 - 255)."
                        ),
                    ));
                }
            }
        }
        ok.then(|| IpAddr::V4(Ipv4Addr::from(bytes)))
    }

    /// An `allow` range; without a prefix, the single address.
    fn range(&mut self, address: &IpAst, prefix: Option<Span>) -> Option<IpRange> {
        let ip = self.ip(address);
        let max: u8 = match ip {
            Some(IpAddr::V6(_)) => 128,
            Some(IpAddr::V4(_)) => 32,
            None if address.octets.is_some() => 32,
            None => 128,
        };
        let prefix = match prefix {
            None => Some(max),
            Some(span) => {
                let text = self.ast.text(span);
                match text.parse::<u8>() {
                    Ok(bits) if bits <= max => Some(bits),
                    _ => {
                        let family = if max == 32 { "IPv4" } else { "IPv6" };
                        self.error(
                            Diagnostic::new(
                                span,
                                format!("prefix length ({text}) is outside of the allowed range (0 - {max})"),
                            )
                            .with_note(format!("an {family} address has {max} bits")),
                        );
                        None
                    }
                }
            }
        };
        Some(IpRange {
            address: ip?,
            prefix: prefix?,
        })
    }
}
