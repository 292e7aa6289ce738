//! The meaning of a `stats` block: its `address`, `port` and `allow` statements are
//! checked as a `udp` block's are, with the statistics endpoint's own defaults
//! (127.0.0.1, port 9100).

use super::Span;
use super::ast::{Ast, SocketSetting};
use super::diagnostic::Diagnostic;
use super::model::{Interface, StatsEndpoint};
use super::sockets::{self, Kind};

/// Checks the statements of a `stats` block; `None` after reporting its errors.
pub(crate) fn check(
    ast: &Ast<'_>,
    _keyword: Span,
    settings: &[SocketSetting],
    errors: &mut Vec<Diagnostic>,
) -> Option<StatsEndpoint> {
    let Interface::Udp(checked) = sockets::check(ast, Kind::Udp, settings, errors)? else {
        return None;
    };
    let defaults = StatsEndpoint::default();
    let given = |f: fn(&SocketSetting) -> bool| settings.iter().any(f);
    Some(StatsEndpoint {
        address: if given(|s| matches!(s, SocketSetting::Address(_))) {
            checked.local_address()
        } else {
            defaults.address
        },
        port: if given(|s| matches!(s, SocketSetting::Port(_))) {
            checked.port
        } else {
            defaults.port
        },
        allow: checked.peers.allow,
    })
}

#[cfg(test)]
mod tests {
    use std::net::IpAddr;

    fn stats(src: &str) -> Option<super::StatsEndpoint> {
        crate::config::load(src).expect("loads").config.stats
    }

    #[test]
    fn defaults_and_values() {
        assert_eq!(stats("udp {}"), None);
        let s = stats("stats {}").expect("configured");
        assert_eq!(
            (s.address, s.port),
            ("127.0.0.1".parse::<IpAddr>().expect("ip"), 9100)
        );
        let s = stats("stats { address ::; port 9200; allow 10.0.0.0/8; }").expect("configured");
        assert_eq!(s.address.to_string(), "::");
        assert_eq!(s.port, 9200);
        assert!(s.allows("10.1.2.3".parse().expect("ip")));
        assert!(s.allows("::ffff:10.1.2.3".parse().expect("ip")));
        assert!(!s.allows("192.168.1.1".parse().expect("ip")));
    }

    #[test]
    fn mistakes_are_reported() {
        for (src, text) in [
            ("stats { port 70000; }", "port"),
            ("stats { connect 1.2.3.4:5; }", "unsupported statement"),
            ("stats {}\nstats {}", "only one 'stats' block"),
        ] {
            let errors = crate::config::load(src).map(|_| ()).expect_err("an error");
            let all: String = errors.iter().map(|d| d.render("f", src)).collect();
            assert!(all.contains(text), "{src}: {all}");
        }
    }
}
