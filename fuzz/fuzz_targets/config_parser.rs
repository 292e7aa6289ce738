//! Any bytes given to the configuration loader yield a configuration or located errors,
//! never a panic; the `--ast` printer and the error renderer cope with whatever parses.
#![no_main]

use libfuzzer_sys::fuzz_target;
use mavtables::config;

fuzz_target!(|data: &[u8]| {
    let src = String::from_utf8_lossy(data);
    match config::load(&src) {
        Ok(loaded) => {
            let c = loaded.config;
            assert!(c.default_chain.0 < c.chains.len());
            if let (Some(link), Some(total)) = (c.queue.link_bytes, c.queue.total_bytes) {
                assert!(total >= link);
            }
            if let Some(path) = &c.signing_state {
                assert!(!path.is_empty());
            }
            if let Some(r) = &c.record {
                // A recording path is a valid pattern, and files hold at least 1 KiB.
                assert!(r.max_file_bytes >= config::Recording::MIN_FILE_BYTES);
                let path = r.path_pattern(|_| None);
                assert!(mavtables::recording::FilePattern::parse(&path).is_ok());
            }
            let keyed = c.interfaces.iter().any(|i| i.signing().is_some());
            assert_eq!(c.signing_state_path(|_| None).is_some(), keyed);
            for iface in &c.interfaces {
                // A key file path is never empty (allow_unsigned alone is an error).
                if let Some(signing) = iface.signing() {
                    assert!(!signing.key_file.is_empty());
                }
                if let config::Interface::WebSocket(w) = iface {
                    for o in &w.origins {
                        // Lower case, a scheme, a host, no path.
                        assert_eq!(*o, o.to_ascii_lowercase());
                        let rest = o
                            .strip_prefix("http://")
                            .or_else(|| o.strip_prefix("https://"));
                        assert!(rest.is_some_and(|r| !r.is_empty() && !r.contains(['/', '?', '#', '@'])));
                    }
                }
                let (connect, peers) = match iface {
                    config::Interface::Udp(u) => (&u.connect, &u.peers),
                    config::Interface::Tcp(t) => (&t.connect, &t.peers),
                    config::Interface::WebSocket(w) => (&None, &w.peers),
                    config::Interface::Serial(_) | config::Interface::Zenoh(_) => continue,
                };
                assert!((1..=65535).contains(&peers.max_peers));
                if let Some(remote) = connect {
                    // A client has one peer: no server limits, and a real port.
                    assert_eq!(*peers, config::PeerLimits::default());
                    assert_ne!(remote.port, 0);
                }
                for range in &peers.allow {
                    assert!(range.prefix <= if range.address.is_ipv4() { 32 } else { 128 });
                }
            }
        }
        Err(errors) => {
            assert!(!errors.is_empty());
            for e in &errors {
                assert!(e.span.start <= src.len() && e.span.end <= src.len());
                let _ = e.render("fuzz.conf", &src);
            }
        }
    }
    if let Ok(ast) = config::parse(&src) {
        let _ = config::print_ast(&ast, "fuzz.conf");
    }
});
