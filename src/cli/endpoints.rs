//! Command-line endpoints: `KIND:VALUE` arguments that stand for a whole configuration
//! (every packet forwarded between the interfaces named), for a quick start without a
//! file. Values are read by the configuration language's own readers, so an endpoint and
//! the block it stands for accept and refuse the same things.

use crate::config::claims::Claim;
use crate::config::net::{self, TextError};
use crate::config::{
    Config, Host, Interface, Remote, SerialInterface, TcpInterface, UdpInterface,
    WebSocketInterface, ZenohInterface, ZenohMode,
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
    ("zenoh-client", "tcp/HOST:PORT", "tcp/127.0.0.1:7447"),
    ("zenoh-peer", "tcp/ADDRESS:PORT", "tcp/0.0.0.0:7448"),
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
        "zenoh-client" | "zenoh-peer" => zenoh_endpoint(value).map(|()| {
            let (mode, connect, listen) = if kind == "zenoh-client" {
                (ZenohMode::Client, vec![value.to_string()], Vec::new())
            } else {
                (ZenohMode::Peer, Vec::new(), vec![value.to_string()])
            };
            Interface::Zenoh(ZenohInterface {
                mode,
                connect,
                listen,
                ..ZenohInterface::default()
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
        if !cfg!(feature = "zenoh") && matches!(e.interface, Interface::Zenoh(_)) {
            return Err(format!(
                "endpoint '{}': this router was built without Zenoh; build one with the Zenoh interface: cargo build --release --features zenoh",
                e.text
            ));
        }
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

/// A Zenoh endpoint, `tcp/HOST:PORT`, read as in a `zenoh` block.
fn zenoh_endpoint(value: &str) -> Result<(), TextError> {
    crate::config::zenoh_block::endpoint(value)
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

    #[test]
    fn zenoh_endpoints_stand_for_a_client_or_a_peer_block() {
        let interface = |arg: &str| parse(arg).expect("valid").expect("endpoint").interface;
        let Interface::Zenoh(z) = interface("zenoh-client:tcp/10.0.0.5:7447") else {
            panic!("zenoh")
        };
        assert_eq!(
            (z.mode, z.connect, z.listen, z.prefix),
            (
                ZenohMode::Client,
                vec!["tcp/10.0.0.5:7447".to_string()],
                vec![],
                "mavtables".into()
            )
        );
        let Interface::Zenoh(z) = interface("zenoh-peer:tcp/[::]:7448") else {
            panic!("zenoh")
        };
        assert_eq!(
            (z.mode, z.connect, z.listen),
            (ZenohMode::Peer, vec![], vec!["tcp/[::]:7448".to_string()])
        );
        for bad in [
            "zenoh-client:10.0.0.5:7447",
            "zenoh-peer:udp/1.2.3.4:7",
            "zenoh-client:tcp/x",
        ] {
            let e = parse(bad).expect_err(bad);
            assert!(e.contains("e.g. zenoh-"), "{e}");
        }
        // A router built without Zenoh says so instead of starting without the link.
        let e = parse("zenoh-client:tcp/127.0.0.1:7447").expect("valid");
        let made = config(&[e.expect("endpoint")]);
        if cfg!(feature = "zenoh") {
            assert!(made.is_ok());
        } else {
            let why = made.expect_err("no zenoh");
            assert!(why.contains("--features zenoh"), "{why}");
        }
    }
}
