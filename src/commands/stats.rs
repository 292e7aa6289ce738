//! `mavtables stats`: asks a running router's statistics endpoint for `/stats` and prints
//! its chains, rules and links like `iptables -L -v`; `--watch` redraws it every second.
//! Its command line is read in [`crate::cli`].

#[doc(hidden)]
pub mod http;
pub(crate) mod render;
pub(crate) mod table;

use std::io::Write;
use std::net::IpAddr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use serde_json::Value;

/// How long one request may take before the router counts as not answering.
pub const TIMEOUT: Duration = Duration::from_secs(3);

/// The statistics version this command reads (`"version"` in `/stats`).
pub const VERSION: u64 = 1;

/// Where the statistics are asked for.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Endpoint {
    /// `HOST:PORT`, IPv6 in brackets.
    pub authority: String,
    /// The path of the JSON statistics (`/stats`, after any prefix the URL had).
    pub path: String,
}

impl Endpoint {
    /// The endpoint of a router whose `stats` block listens on `address` and `port`: a
    /// wildcard address (`0.0.0.0`, `::`) is asked on loopback.
    pub fn of_listener(address: IpAddr, port: u16) -> Self {
        let address = match address {
            IpAddr::V4(a) if a.is_unspecified() => IpAddr::from([127, 0, 0, 1]),
            IpAddr::V6(a) if a.is_unspecified() => IpAddr::V6(std::net::Ipv6Addr::LOCALHOST),
            other => other,
        };
        let authority = match address {
            IpAddr::V4(a) => format!("{a}:{port}"),
            IpAddr::V6(a) => format!("[{a}]:{port}"),
        };
        Endpoint {
            authority,
            path: "/stats".into(),
        }
    }

    /// The endpoint of `--url http://HOST:PORT[/PREFIX]`: `/stats` under the prefix.
    pub(crate) fn from_url(url: &str) -> Result<Self, String> {
        let bad = |why: &str| {
            format!("--url '{url}': {why}; write http://HOST:PORT, e.g. http://127.0.0.1:9100")
        };
        let rest = url
            .strip_prefix("http://")
            .ok_or_else(|| bad("only http:// is understood"))?;
        let (authority, prefix) = match rest.find('/') {
            Some(i) => (&rest[..i], &rest[i..]),
            None => (rest, ""),
        };
        let port_text = match authority.rsplit_once(':') {
            Some((host, port)) if !host.is_empty() && !host.ends_with(':') => port,
            _ => return Err(bad("expected HOST:PORT")),
        };
        if port_text.parse::<u16>().map_or(true, |p| p == 0) {
            return Err(bad("the port is not a number from 1 to 65535"));
        }
        let prefix = prefix.trim_end_matches('/');
        let prefix = prefix.strip_suffix("/stats").unwrap_or(prefix);
        if prefix.chars().any(|c| c.is_whitespace() || c.is_control()) {
            return Err(bad("the path holds spaces"));
        }
        Ok(Endpoint {
            authority: authority.to_string(),
            path: format!("{prefix}/stats"),
        })
    }

    /// The URL of the statistics, as shown in the output.
    pub(crate) fn url(&self) -> String {
        format!("http://{}{}", self.authority, self.path)
    }
}

/// The router's statistics, or one line saying why there are none.
pub fn fetch(endpoint: &Endpoint) -> Result<Value, String> {
    fetch_query(endpoint, "")
}

/// The statistics with only the rate history the tables need (the `silent` state looks
/// at the last [`render::SILENT_SAMPLES`]): a fraction of the whole at many links. A
/// router from before the `history` parameter ignores it and sends everything.
fn fetch_for_tables(endpoint: &Endpoint) -> Result<Value, String> {
    fetch_query(endpoint, &format!("?history={}", render::SILENT_SAMPLES))
}

/// The statistics at the endpoint's path followed by `query` (empty, or from `?`).
fn fetch_query(endpoint: &Endpoint, query: &str) -> Result<Value, String> {
    let target = format!("{}{query}", endpoint.path);
    let body = http::get(&endpoint.authority, &target, TIMEOUT)?;
    let stats: Value = serde_json::from_slice(&body)
        .map_err(|e| format!("{} is not statistics JSON: {e}", endpoint.url()))?;
    match stats.get("version").and_then(Value::as_u64) {
        Some(VERSION) => Ok(stats),
        Some(v) => Err(format!(
            "{} has statistics version {v}; this mavtables reads version {VERSION}",
            endpoint.url()
        )),
        None => Err(format!("{} is not mavtables statistics", endpoint.url())),
    }
}

/// Prints the statistics once.
pub(crate) fn show(
    endpoint: &Endpoint,
    view: &render::View,
    out: &mut dyn Write,
) -> Result<(), String> {
    let stats = fetch_for_tables(endpoint)?;
    out.write_all(render::render(&stats, &endpoint.url(), view).as_bytes())
        .and_then(|()| out.flush())
        .map_err(|e| format!("writing output: {e}"))
}

/// Redraws the statistics every second until `stop` is set (Ctrl-C). On a `terminal`
/// each picture replaces the last, as `top` does, on the alternate screen, which is left
/// on exit; otherwise pictures follow each other plainly, separated by a blank line.
/// A router that does not answer is shown as such and asked again a second later.
pub(crate) fn watch(
    endpoint: &Endpoint,
    view: &render::View,
    out: &mut dyn Write,
    terminal: bool,
    stop: &AtomicBool,
) -> std::io::Result<()> {
    if terminal {
        // Alternate screen, cursor hidden.
        out.write_all(b"\x1b[?1049h\x1b[?25l")?;
    }
    let result = watch_loop(endpoint, view, out, terminal, stop);
    if terminal {
        // Back to the normal screen, cursor shown: the shell is as it was.
        let _ = out.write_all(b"\x1b[?25h\x1b[?1049l");
        let _ = out.flush();
    }
    result
}

fn watch_loop(
    endpoint: &Endpoint,
    view: &render::View,
    out: &mut dyn Write,
    terminal: bool,
    stop: &AtomicBool,
) -> std::io::Result<()> {
    let mut first = true;
    while !stop.load(Ordering::Relaxed) {
        let started = Instant::now();
        let text = match fetch_for_tables(endpoint) {
            Ok(stats) => render::render(&stats, &endpoint.url(), view),
            Err(e) => format!("router not answering: {e}\n"),
        };
        if terminal {
            // Home, the picture, then clear whatever the last (longer) picture left.
            out.write_all(b"\x1b[H")?;
            out.write_all(text.replace('\n', "\x1b[K\n").as_bytes())?;
            out.write_all(b"\x1b[J")?;
        } else {
            if !first {
                out.write_all(b"\n")?;
            }
            out.write_all(text.as_bytes())?;
        }
        out.flush()?;
        first = false;
        let next = started + Duration::from_secs(1);
        while !stop.load(Ordering::Relaxed) && Instant::now() < next {
            std::thread::sleep(Duration::from_millis(20));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn urls_and_listeners() {
        let e = Endpoint::from_url("http://127.0.0.1:9100").unwrap();
        assert_eq!(e.authority, "127.0.0.1:9100");
        assert_eq!(e.path, "/stats");
        assert_eq!(e.url(), "http://127.0.0.1:9100/stats");
        assert_eq!(
            Endpoint::from_url("http://[::1]:9100/").unwrap().url(),
            "http://[::1]:9100/stats"
        );
        assert_eq!(
            Endpoint::from_url("http://gw.local:80/mav/stats")
                .unwrap()
                .url(),
            "http://gw.local:80/mav/stats"
        );
        for bad in [
            "https://a:1",
            "http://a",
            "http://:1",
            "http://a:0",
            "http://a:x",
            "http://a:1/b c",
        ] {
            assert!(Endpoint::from_url(bad).is_err(), "{bad}");
        }
        assert_eq!(
            Endpoint::of_listener("0.0.0.0".parse().unwrap(), 9100).url(),
            "http://127.0.0.1:9100/stats"
        );
        assert_eq!(
            Endpoint::of_listener("::".parse().unwrap(), 1).url(),
            "http://[::1]:1/stats"
        );
        assert_eq!(
            Endpoint::of_listener("10.0.0.2".parse().unwrap(), 1).authority,
            "10.0.0.2:1"
        );
    }
}
