//! A simulated network around the routing core: configs from text, frames by message name,
//! links by name, an injected clock, and logs as the original's texts.
#![allow(dead_code)]

use std::collections::BTreeMap;

use mavtables::address::Address;
use mavtables::config;
use mavtables::dialect;
use mavtables::routing::{LinkId, Output, Router, RouterOptions, Timestamp};
use mavtables::wire::Frame;
use mavtables::wire::encode::{Header, encode_v1, encode_v2};

/// The default router options with queues of `per_link` bytes each and `shared` bytes
/// in all.
pub fn queue_options(per_link: usize, shared: usize) -> RouterOptions {
    RouterOptions {
        queue_capacity: per_link,
        total_queue_capacity: shared,
        ..RouterOptions::default()
    }
}

/// Parses `S.C`.
pub fn addr(s: &str) -> Address {
    let (a, b) = s.split_once('.').expect("S.C");
    Address::new(a.parse().expect("system"), b.parse().expect("component"))
}

/// A full-length MAVLink 2 frame of message `name` from `from`, with its target fields
/// set to `to` (0.0 when `None` and the message has target fields).
pub fn frame(name: &str, from: &str, to: Option<&str>) -> Vec<u8> {
    build(name, from, to, 2, 0)
}

/// [`frame`] with sequence number `seq` (frames that differ only in it).
pub fn frame_seq(name: &str, from: &str, to: Option<&str>, seq: u8) -> Vec<u8> {
    build(name, from, to, 2, seq)
}

/// A MAVLink 1 frame of message `name` from `from`, with its target fields set to `to`.
pub fn frame_v1(name: &str, from: &str, to: Option<&str>) -> Vec<u8> {
    build(name, from, to, 1, 0)
}

fn build(name: &str, from: &str, to: Option<&str>, version: u8, seq: u8) -> Vec<u8> {
    let info = dialect::by_name(name).unwrap_or_else(|| panic!("no message {name}"));
    // Non-zero filler keeps MAVLink 2 frames at full length (no trailing-zero truncation).
    let mut payload = vec![0x55u8; info.max_len as usize];
    let t = to.map(addr).unwrap_or_default();
    if to.is_some() || info.target_system_offset.is_some() {
        let sys = info.target_system_offset.expect("message has a target") as usize;
        payload[sys] = t.system;
        if let Some(c) = info.target_component_offset {
            payload[c as usize] = t.component;
        } else {
            assert_eq!(t.component, 0, "{name} has no target_component");
        }
    }
    let src = addr(from);
    let header = Header {
        seq,
        system: src.system,
        component: src.component,
    };
    let mut out = Vec::new();
    if version == 1 {
        encode_v1(header, info.id, &payload, &mut out).expect("encode v1");
    } else {
        encode_v2(header, info.id, &payload, None, &mut out).expect("encode v2");
    }
    out
}

/// The router, its links by name, the clock and everything it logged.
pub struct Net {
    pub router: Router,
    pub links: BTreeMap<String, LinkId>,
    pub now: Timestamp,
    pub log: Vec<String>,
    pub out: Output,
    /// Queue drops reported by the router so far.
    pub drops: u64,
}

impl Net {
    /// A router for the configuration text `conf`; its serial interfaces become links
    /// (with their preloads) at time 0, as the I/O layer does at start.
    pub fn new(conf: &str) -> Net {
        Net::with_options(conf, RouterOptions::default())
    }

    /// Like [`Net::new`] with tunables.
    pub fn with_options(conf: &str, options: RouterOptions) -> Net {
        let config = config::load(conf)
            .unwrap_or_else(|e| panic!("config does not load: {e:?}"))
            .config;
        let mut net = Net {
            router: Router::with_options(&config, options),
            links: BTreeMap::new(),
            now: Timestamp::ZERO,
            log: Vec::new(),
            out: Output::default(),
            drops: 0,
        };
        for iface in &config.interfaces {
            if let config::Interface::Serial(s) = iface {
                let id = net
                    .router
                    .add_serial_link(&s.device, &s.preload, net.now, &mut net.out);
                net.links.insert(s.device.clone(), id);
            }
        }
        net.flush();
        net
    }

    fn flush(&mut self) {
        self.drops += self.out.queue_drops;
        self.log
            .extend(self.out.events.iter().map(|e| e.to_string()));
        self.out.clear();
    }

    /// Sets the clock to `secs` seconds after the start.
    pub fn at(&mut self, secs: u64) -> &mut Net {
        self.now = Timestamp::from_secs(secs);
        self
    }

    /// Delivers `bytes` (one frame) as received on link `link` (a UDP link is created on
    /// its first frame, like the I/O layer does).
    pub fn recv(&mut self, link: &str, bytes: &[u8]) {
        let frame = Frame::parse_exact(bytes).expect("valid frame");
        let id = match self.links.get(link) {
            Some(&id) => id,
            None => {
                let id = self.router.add_udp_link(link, self.now);
                self.links.insert(link.to_string(), id);
                id
            }
        };
        self.router.receive(id, &frame, self.now, &mut self.out);
        self.flush();
    }

    /// Sends message `name` from `from` (targeted at `to`) on `link`.
    pub fn send(&mut self, link: &str, name: &str, from: &str, to: Option<&str>) {
        let f = frame(name, from, to);
        self.recv(link, &f);
    }

    /// Makes `addr` known on `link` with a HEARTBEAT (rejected by most test configs).
    pub fn heartbeat(&mut self, link: &str, from: &str) {
        self.send(link, "HEARTBEAT", from, None);
    }

    /// Takes the log so far.
    pub fn take_log(&mut self) -> Vec<String> {
        std::mem::take(&mut self.log)
    }

    /// Everything queued on `link`, in send order, as packet texts.
    pub fn drain(&mut self, link: &str) -> Vec<String> {
        let id = self.links[link];
        std::iter::from_fn(|| self.router.pop(id))
            .map(|p| {
                Frame::parse_exact(&p)
                    .expect("queued bytes are a frame")
                    .to_string()
            })
            .collect()
    }

    /// Runs housekeeping at the current time; returns the names of removed links.
    pub fn tick(&mut self) -> Vec<String> {
        let removed = self.router.tick(self.now);
        let names: Vec<String> = self
            .links
            .iter()
            .filter(|(_, id)| removed.contains(id))
            .map(|(n, _)| n.clone())
            .collect();
        for n in &names {
            self.links.remove(n);
        }
        names
    }
}
