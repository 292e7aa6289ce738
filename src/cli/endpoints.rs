//! Command-line endpoints: `KIND:VALUE` arguments that stand for a whole configuration
//! (every packet forwarded between the interfaces named), for a quick start without a
//! file. Values are read by the configuration language's own readers, so an endpoint and
//! the block it stands for accept and refuse the same things.

use crate::config::claims::Claim;
use crate::config::net::{self, TextError};
use crate::config::{
    Config, Host, Interface, Remote, SerialInterface, TcpInterface, UdpInterface,
    WebSocketInterface,
};
use std::net::IpAddr;

/// The endpoint kinds, each with its form and an example (as `--help` lists them).
pub const KINDS: &[(&str, &str, &str)] = &[
    ("serial", "DEVICE:BAUD", "/dev/ttyACM0:115200"),
    ("udp-server", "ADDRESS:PORT", "0.0.0.0:14550"),
    ("udp-client", "HOST:PORT", "127.0.0.1:14550"),
    ("tcp-server", "ADDRESS:PORT", "0.0.0.0:5760"),
    ("tcp-client", "HOST:PORT", "localhost:5760"),
    ("ws-server", "ADDRESS:PORT", "127.0.0.1:8765"),
];

/// One endpoint argument and the interface it stands for.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Endpoint {
    /// The argument as given (for messages).
    pub text: String,
    /// The interface it opens.
    pub interface: Interface,
}

/// Reads `arg` as an endpoint: `Ok(None)` when it does not start with a known `KIND:`
/// (such arguments are ignored, as the original ignored every positional argument), an
/// error naming the argument when the value is malformed.
pub fn parse(arg: &str) -> Result<Option<Endpoint>, String> {
    let Some((kind, value)) = arg.split_once(':') else {
        return Ok(None);
    };
    let Some((_, form, example)) = KINDS.iter().find(|(k, _, _)| *k == kind) else {
        return Ok(None);
    };
    let interface = match kind {
        "serial" => serial(value),
        "udp-server" => server(value).map(|(address, port)| {
            Interface::Udp(UdpInterface {
                port,
                address: Some(address),
                ..UdpInterface::default()
            })
        }),
        "udp-client" => client(value).map(|remote| {
            Interface::Udp(UdpInterface {
                port: 0,
                connect: Some(remote),
                ..UdpInterface::default()
            })
        }),
        "tcp-server" => server(value).map(|(address, port)| {
            Interface::Tcp(TcpInterface {
                port,
                address: Some(address),
                ..TcpInterface::default()
            })
        }),
        "ws-server" => server(value).map(|(address, port)| {
            Interface::WebSocket(WebSocketInterface {
                port,
                address: Some(address),
                ..WebSocketInterface::default()
            })
        }),
        _ => client(value).map(|remote| {
            Interface::Tcp(TcpInterface {
                connect: Some(remote),
                ..TcpInterface::default()
            })
        }),
    };
    match interface {
        Ok(interface) => Ok(Some(Endpoint {
            text: arg.to_string(),
            interface,
        })),
        Err(e) => {
            // The generic form follows anyway; a more specific hint goes in parentheses.
            let hint = match e.note {
                Some(note) if !note.starts_with("write HOST") => format!(" ({note})"),
                _ => String::new(),
            };
            Err(format!(
                "endpoint '{arg}': {}{hint}; write {kind}:{form}, e.g. {kind}:{example}",
                e.message
            ))
        }
    }
}

/// The configuration `endpoints` stand for: their interfaces in the order given, every
/// packet accepted. Two endpoints claiming one local socket or device are refused.
pub(crate) fn config(endpoints: &[Endpoint]) -> Result<Config, String> {
    let mut claimed: Vec<(Claim, &str)> = Vec::new();
    for e in endpoints {
        let Some(claim) = Claim::of(&e.interface) else {
            continue;
        };
        if let Some((other, first)) = claimed.iter().find(|(c, _)| c.clashes(&claim)) {
            return Err(format!(
                "endpoint '{}' clashes with endpoint '{first}': both need {} {other}",
                e.text,
                other.kind()
            ));
        }
        claimed.push((claim, &e.text));
    }
    Ok(Config::accept_all(
        endpoints.iter().map(|e| e.interface.clone()).collect(),
    ))
}

/// `DEVICE:BAUD`; the device may itself hold `:` (the baud rate follows the last one).
fn serial(value: &str) -> Result<Interface, TextError> {
    let bad = |message: &str| TextError {
        at: 0..value.len(),
        message: message.to_string(),
        note: None,
    };
    let Some((device, baud)) = value.rsplit_once(':') else {
        return Err(bad("expected ':' and a baud rate after the device"));
    };
    if device.is_empty() {
        return Err(bad("expected a device before ':'"));
    }
    let baudrate = match baud.parse::<u32>() {
        Ok(b) if b > 0 && baud.bytes().all(|c| c.is_ascii_digit()) => b,
        _ => {
            return Err(bad(&format!(
                "baud rate ({baud}) is not a number from 1 to 4294967295"
            )));
        }
    };
    Ok(Interface::Serial(SerialInterface {
        device: device.to_string(),
        baudrate,
        flow_control: false,
        preload: Vec::new(),
        max_bitrate: None,
        signing: None,
    }))
}

/// `HOST:PORT` of a client.
fn client(value: &str) -> Result<Remote, TextError> {
    let hp = net::split_host_port(value)?;
    Ok(Remote {
        host: net::host(&value[hp.host], hp.bracketed)?,
        port: net::port(&value[hp.port], 1)?,
    })
}

/// `ADDRESS:PORT` of a server: an IP address (IPv6 in brackets) and a port (0 = any).
fn server(value: &str) -> Result<(IpAddr, u16), TextError> {
    let hp = net::split_host_port(value)?;
    let text = &value[hp.host.clone()];
    let address = match net::host(text, hp.bracketed)? {
        Host::Ip(ip) => ip,
        Host::Name(_) => {
            return Err(TextError {
                at: hp.host,
                message: format!("a server listens on an IP address, not a host name ('{text}')"),
                note: None,
            });
        }
    };
    Ok((address, net::port(&value[hp.port], 0)?))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unknown_kinds_are_not_endpoints() {
        for arg in ["file.conf", "udp:1.2.3.4:5", "UDP-CLIENT:a:1", "serial"] {
            assert_eq!(parse(arg), Ok(None), "{arg}");
        }
    }

    #[test]
    fn serial_devices_may_hold_colons() {
        let e = parse("serial:/dev/serial/by-id/usb-A:1-if00:921600")
            .expect("valid")
            .expect("endpoint");
        let Interface::Serial(s) = e.interface else {
            panic!("serial")
        };
        assert_eq!(
            (s.device.as_str(), s.baudrate),
            ("/dev/serial/by-id/usb-A:1-if00", 921_600)
        );
        assert!(parse("serial:/dev/ttyACM0").is_err());
        assert!(parse("serial::9600").is_err());
        assert!(parse("serial:/dev/x:0").is_err());
        assert!(parse("serial:/dev/x:+5").is_err());
    }
}
