//! Network values of the configuration: where a client connects ([`Remote`], [`Host`]),
//! which addresses a server takes ([`IpRange`]), and how their text is read. The readers
//! are shared by the configuration file and the command-line endpoints, and report a
//! [`TextError`] located inside the text they were given.

use std::fmt;
use std::net::{IpAddr, Ipv4Addr, Ipv6Addr};
use std::ops::Range;

/// Where a client connects: a host and a port.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Remote {
    /// The peer's address or host name.
    pub host: Host,
    /// The peer's port (1 – 65535).
    pub port: u16,
}

impl fmt::Display for Remote {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.host {
            Host::Ip(IpAddr::V6(ip)) => write!(f, "[{ip}]:{}", self.port),
            Host::Ip(IpAddr::V4(ip)) => write!(f, "{ip}:{}", self.port),
            Host::Name(name) => write!(f, "{name}:{}", self.port),
        }
    }
}

/// The host part of a [`Remote`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Host {
    /// An IP address, used as it is.
    Ip(IpAddr),
    /// A host name, resolved when the interface is opened (not at configuration time).
    Name(String),
}

/// An IP address range for `allow` (IPv4 or IPv6, prefix length in bits).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct IpRange {
    /// The address as written (bits after the prefix are ignored).
    pub address: IpAddr,
    /// How many leading bits must match: at most 32 for IPv4, 128 for IPv6.
    pub prefix: u8,
}

impl IpRange {
    /// Whether `ip` is in the range. An IPv4-mapped IPv6 address (`::ffff:a.b.c.d`, as a
    /// dual-stack socket reports IPv4 peers) counts as the IPv4 address `a.b.c.d`.
    pub(crate) fn contains(&self, ip: IpAddr) -> bool {
        let ip = match ip {
            IpAddr::V6(v6) => v6.to_ipv4_mapped().map_or(ip, IpAddr::V4),
            v4 => v4,
        };
        match (self.address, ip) {
            (IpAddr::V4(net), IpAddr::V4(ip)) => {
                prefix_match(&net.octets(), &ip.octets(), self.prefix)
            }
            (IpAddr::V6(net), IpAddr::V6(ip)) => {
                prefix_match(&net.octets(), &ip.octets(), self.prefix)
            }
            _ => false,
        }
    }
}

/// Whether the first `bits` bits of `a` and `b` are equal.
fn prefix_match(a: &[u8], b: &[u8], bits: u8) -> bool {
    let bits = usize::from(bits).min(a.len() * 8);
    let (whole, rest) = (bits / 8, bits % 8);
    if a[..whole] != b[..whole] {
        return false;
    }
    if rest == 0 {
        return true;
    }
    let mask = 0xFFu8 << (8 - rest);
    a[whole] & mask == b[whole] & mask
}

impl fmt::Display for IpRange {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.address, self.prefix)
    }
}

/// A mistake found in a piece of text: where (byte range within that text) and what.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct TextError {
    /// The bytes at fault (empty: the place where something is missing).
    pub at: Range<usize>,
    /// What is wrong, in one line.
    pub message: String,
    /// A hint on how to write it instead.
    pub note: Option<String>,
}

impl TextError {
    fn new(at: Range<usize>, message: impl Into<String>) -> Self {
        TextError {
            at,
            message: message.into(),
            note: None,
        }
    }

    fn with_note(mut self, note: impl Into<String>) -> Self {
        self.note = Some(note.into());
        self
    }
}

/// `HOST:PORT` split into its parts (byte ranges within the text), syntax only.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct HostPort {
    /// The host, without brackets.
    pub host: Range<usize>,
    /// True when the host was written in brackets (an IPv6 address).
    pub bracketed: bool,
    /// The port digits.
    pub port: Range<usize>,
}

/// Splits `HOST:PORT`, `[IPV6]:PORT`: the shape only; [`host`] and [`port`] check the
/// values.
pub(crate) fn split_host_port(text: &str) -> Result<HostPort, TextError> {
    let end = text.len();
    let (host, bracketed, rest) = if let Some(inner) = text.strip_prefix('[') {
        let Some(close) = inner.find(']') else {
            return Err(TextError::new(
                end..end,
                "expected ']' closing the IPv6 address",
            ));
        };
        (1..1 + close, true, 2 + close)
    } else {
        let colons = text.matches(':').count();
        if colons >= 2 {
            let last = text.rfind(':').unwrap_or(end);
            return Err(
                TextError::new(0..end, "an IPv6 address must be written in brackets")
                    .with_note(format!("write [{}]{}", &text[..last], &text[last..])),
            );
        }
        match text.find(':') {
            Some(colon) => (0..colon, false, colon),
            None => {
                return Err(TextError::new(
                    end..end,
                    "expected ':' and a port number after the host",
                )
                .with_note("write HOST:PORT, e.g. 192.168.1.50:14550"));
            }
        }
    };
    if host.is_empty() {
        return Err(TextError::new(
            0..rest.min(end),
            "expected a host (an IP address or a host name) before ':'",
        ));
    }
    if !text[rest..].starts_with(':') {
        return Err(TextError::new(
            rest..end.max(rest),
            "expected ':' and a port number after ']'",
        )
        .with_note("write [IPV6]:PORT, e.g. [fd00::7]:14550"));
    }
    let port = rest + 1..end;
    if port.is_empty() {
        return Err(TextError::new(end..end, "expected a port number after ':'"));
    }
    if !text[port.clone()].bytes().all(|b| b.is_ascii_digit()) {
        return Err(TextError::new(port, "expected a valid port number"));
    }
    Ok(HostPort {
        host,
        bracketed,
        port,
    })
}

/// A port number written in decimal, within `min..=65535`.
pub(crate) fn port(text: &str, min: u16) -> Result<u16, TextError> {
    match text.parse::<u64>() {
        Ok(v) if (u64::from(min)..=65535).contains(&v) => Ok(v as u16),
        _ => Err(TextError::new(
            0..text.len(),
            format!("port number ({text}) is outside of the allowed range ({min} - 65535)"),
        )),
    }
}

/// The host of a `connect`: an IPv6 address (when `bracketed`), an IPv4 address (text of
/// digits and dots only) or a host name (letters, digits, `-` and `.`).
pub(crate) fn host(text: &str, bracketed: bool) -> Result<Host, TextError> {
    if bracketed {
        return text
            .parse::<Ipv6Addr>()
            .map(|ip| Host::Ip(IpAddr::V6(ip)))
            .map_err(|_| {
                TextError::new(
                    0..text.len(),
                    format!("'{text}' is not a valid IPv6 address"),
                )
            });
    }
    if text.bytes().all(|b| b.is_ascii_digit() || b == b'.') {
        return ipv4(text).map(|ip| Host::Ip(IpAddr::V4(ip)));
    }
    host_name(text).map(|()| Host::Name(text.to_string()))
}

/// An IPv4 address `a.b.c.d`; a part above 255 is pointed at.
pub(crate) fn ipv4(text: &str) -> Result<Ipv4Addr, TextError> {
    let mut octets = [0u8; 4];
    let mut count = 0;
    let mut start = 0;
    for part in text.split('.') {
        let at = start..start + part.len();
        start += part.len() + 1;
        if count == 4 || part.is_empty() || !part.bytes().all(|b| b.is_ascii_digit()) {
            count = 5;
            break;
        }
        match part.parse::<u8>() {
            Ok(v) => octets[count] = v,
            Err(_) => {
                return Err(TextError::new(
                    at,
                    format!(
                        "'{text}' is not a valid IPv4 address: {part} is outside of the allowed range (0 - 255)"
                    ),
                ));
            }
        }
        count += 1;
    }
    if count != 4 {
        return Err(TextError::new(
            0..text.len(),
            format!("'{text}' is not a valid IPv4 address"),
        )
        .with_note("an IPv4 address is four numbers 0 - 255 separated by '.'"));
    }
    Ok(Ipv4Addr::from(octets))
}

/// Checks a host name: labels of letters, digits and `-` (not at either end of a label),
/// separated by `.`; at most 253 characters.
pub(crate) fn host_name(text: &str) -> Result<(), TextError> {
    const NOTE: &str = "a host name is made of letters, digits, '-' and '.'";
    if let Some((i, c)) = text
        .char_indices()
        .find(|(_, c)| !(c.is_ascii_alphanumeric() || matches!(c, '-' | '.')))
    {
        return Err(TextError::new(
            i..i + c.len_utf8(),
            format!("'{text}' is not a valid host name: '{c}' is not allowed"),
        )
        .with_note(NOTE));
    }
    if text.len() > 253 {
        return Err(TextError::new(
            0..text.len(),
            "the host name is longer than 253 characters",
        ));
    }
    let mut start = 0;
    for label in text.split('.') {
        let at = start..start + label.len();
        start += label.len() + 1;
        if label.is_empty() || label.len() > 63 || label.starts_with('-') || label.ends_with('-') {
            return Err(TextError::new(
                at,
                format!(
                    "'{text}' is not a valid host name: each part between dots needs 1 - 63 characters and cannot start or end with '-'"
                ),
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v4(s: &str) -> IpAddr {
        s.parse().expect("address")
    }

    #[test]
    fn ranges_match_by_prefix_and_map_ipv4_in_ipv6() {
        let lan = IpRange {
            address: v4("192.168.1.0"),
            prefix: 24,
        };
        assert!(lan.contains(v4("192.168.1.77")));
        assert!(!lan.contains(v4("192.168.2.1")));
        assert!(lan.contains(v4("::ffff:192.168.1.9")));
        assert!(!lan.contains(v4("fd00::1")));
        let odd = IpRange {
            address: v4("10.0.0.0"),
            prefix: 9,
        };
        assert!(odd.contains(v4("10.127.255.255")));
        assert!(!odd.contains(v4("10.128.0.0")));
        let ula = IpRange {
            address: v4("fd00::"),
            prefix: 8,
        };
        assert!(ula.contains(v4("fdff::1")));
        assert!(!ula.contains(v4("fe80::1")));
        assert!(!ula.contains(v4("10.0.0.1")));
        let all = IpRange {
            address: v4("0.0.0.0"),
            prefix: 0,
        };
        assert!(all.contains(v4("8.8.8.8")));
        assert_eq!(lan.to_string(), "192.168.1.0/24");
    }

    #[test]
    fn remotes_display_with_brackets_for_ipv6() {
        let r = |host, port| Remote { host, port }.to_string();
        assert_eq!(r(Host::Ip(v4("1.2.3.4")), 14550), "1.2.3.4:14550");
        assert_eq!(r(Host::Ip(v4("fd00::7")), 14550), "[fd00::7]:14550");
        assert_eq!(r(Host::Name("localhost".into()), 5760), "localhost:5760");
    }

    #[test]
    fn host_port_shapes() {
        let hp = split_host_port("[fd00::7]:14550").expect("ok");
        assert_eq!((hp.host, hp.bracketed, hp.port), (1..8, true, 10..15));
        let hp = split_host_port("localhost:5760").expect("ok");
        assert_eq!((hp.host, hp.bracketed, hp.port), (0..9, false, 10..14));
        let err = |s: &str| split_host_port(s).expect_err(s);
        assert_eq!(err("10.0.0.1").at, 8..8);
        assert!(err("10.0.0.1").message.contains("expected ':' and a port"));
        let e = err("fd00::7:14550");
        assert_eq!(e.note.as_deref(), Some("write [fd00::7]:14550"));
        assert_eq!(
            err("[::1]").message,
            "expected ':' and a port number after ']'"
        );
        assert_eq!(err("[::1").message, "expected ']' closing the IPv6 address");
        assert_eq!(err(":5").at, 0..0);
        assert_eq!(err("a:").message, "expected a port number after ':'");
        assert_eq!(err("a:5x").at, 2..4);
    }

    #[test]
    fn hosts_and_ports() {
        assert_eq!(host("10.0.0.1", false), Ok(Host::Ip(v4("10.0.0.1"))));
        assert_eq!(host("::1", true), Ok(Host::Ip(v4("::1"))));
        assert_eq!(
            host("gcs-1.local", false),
            Ok(Host::Name("gcs-1.local".into()))
        );
        let e = host("300.1.1.1", false).expect_err("octet");
        assert_eq!(e.at, 0..3);
        assert!(e.message.contains("not a valid IPv4 address"));
        assert_eq!(host("1.2.3", false).expect_err("short").at, 0..5);
        assert_eq!(host("1.2.3.4.5", false).expect_err("long").at, 0..9);
        let e = host("exa_mple", false).expect_err("underscore");
        assert_eq!(e.at, 3..4);
        assert_eq!(host("a..b", false).expect_err("empty label").at, 2..2);
        assert_eq!(host("-a", false).expect_err("dash").at, 0..2);
        assert!(host("1.2.3.4", true).is_err());
        assert_eq!(port("14550", 1), Ok(14550));
        assert!(port("0", 1).is_err());
        assert_eq!(port("0", 0), Ok(0));
        assert_eq!(
            port("65536", 1).expect_err("big").message,
            "port number (65536) is outside of the allowed range (1 - 65535)"
        );
    }
}
