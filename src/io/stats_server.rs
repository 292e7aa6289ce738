//! The statistics endpoint: a small HTTP/1.1 server on threads of its own that answers
//! `GET /metrics` (Prometheus text), `GET /stats` (JSON) and `GET /` (the status page)
//! from the latest snapshot the event loop published; `HEAD` gets the same headers without
//! the body, and the absolute request form (`GET http://HOST:PORT/stats`) is understood.
//!
//! It never touches the event loop: the loop publishes a snapshot about once a second
//! (one `Arc` swapped under a mutex held for nothing else), and requests are read,
//! rendered and answered here. Each connection gets a thread, at most
//! [`MAX_CONNECTIONS`] at once (further ones are closed at once); its request head must
//! arrive whole within [`DEADLINE`] and fit in [`MAX_HEAD`] bytes, and its answer must
//! be taken within [`DEADLINE`] too, so a silent or slow client holds one thread for at
//! most twice that and never anything the router needs. One request per connection
//! (`Connection: close`). Listening on a loopback address, it answers only requests
//! whose `Host` names this machine (an IP address or `localhost`): a web page from
//! elsewhere whose name was made to point at 127.0.0.1 (DNS rebinding) gets 403.

use std::io::{self, Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

use crate::config::StatsEndpoint;
use crate::stats::history_query::HistoryQuery;
use crate::stats::{self, StatsSnapshot};

/// Longest a client may take to send its request head, and again to take the answer.
pub const DEADLINE: Duration = Duration::from_secs(2);
/// Largest request head read (bytes); a longer one is answered 431.
pub const MAX_HEAD: usize = 8192;
/// Connections served at once; more are closed unanswered.
pub const MAX_CONNECTIONS: usize = 8;
/// Most headers a request may have.
const MAX_HEADERS: usize = 64;

/// The latest snapshot, shared between the event loop and the server's threads.
type Latest = Arc<Mutex<Arc<StatsSnapshot>>>;

/// The `stats` block it serves as: its `allow` ranges may change while it runs.
type Settings = Arc<Mutex<StatsEndpoint>>;

/// A running statistics endpoint; the event loop gives it snapshots. Dropping it stops
/// it and frees its port (a reload that moves the `stats` block) before it returns.
pub struct StatsServer {
    latest: Latest,
    settings: Settings,
    address: SocketAddr,
    stop: Arc<AtomicBool>,
    accepting: Option<JoinHandle<()>>,
}

impl StatsServer {
    /// Listens as `endpoint` says and serves from a thread of its own.
    pub(crate) fn start(endpoint: &StatsEndpoint) -> io::Result<StatsServer> {
        let listener = TcpListener::bind(SocketAddr::new(endpoint.address, endpoint.port))?;
        let address = listener.local_addr()?;
        let latest: Latest = Arc::default();
        let shared = latest.clone();
        let settings: Settings = Arc::new(Mutex::new(endpoint.clone()));
        let serving = settings.clone();
        let stop = Arc::new(AtomicBool::new(false));
        let stopped = stop.clone();
        let accepting = thread::Builder::new()
            .name("stats-http".into())
            .spawn(move || accept_loop(&listener, &serving, &shared, &stopped))?;
        Ok(StatsServer {
            latest,
            settings,
            address,
            stop,
            accepting: Some(accepting),
        })
    }

    /// Serves as `endpoint` from now on if it listens where this one does (only its
    /// `allow` ranges differ): true then, and the port is kept; false if it must be
    /// started anew.
    pub(crate) fn reconfigure(&self, endpoint: &StatsEndpoint) -> bool {
        let mut settings = self.settings.lock().unwrap_or_else(PoisonError::into_inner);
        if (settings.address, settings.port) != (endpoint.address, endpoint.port) {
            return false;
        }
        *settings = endpoint.clone();
        true
    }

    /// Where it listens.
    pub(crate) fn address(&self) -> SocketAddr {
        self.address
    }

    /// Makes `snapshot` the one requests are answered from.
    pub(crate) fn publish(&self, snapshot: StatsSnapshot) {
        let snapshot = Arc::new(snapshot);
        *self.latest.lock().unwrap_or_else(PoisonError::into_inner) = snapshot;
    }
}

impl Drop for StatsServer {
    /// Stops the accepting thread (woken by a connection of our own) and waits for it to
    /// close the listening socket, so that the port is free when this returns; requests
    /// being answered finish on their own threads.
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Release);
        let mut to = self.address;
        if to.ip().is_unspecified() {
            to.set_ip(match to {
                SocketAddr::V4(_) => std::net::Ipv4Addr::LOCALHOST.into(),
                SocketAddr::V6(_) => std::net::Ipv6Addr::LOCALHOST.into(),
            });
        }
        let woken = TcpStream::connect_timeout(&to, Duration::from_millis(200)).is_ok();
        // Only a thread that was woken is waited for: one that was not would never end.
        if let Some(accepting) = self.accepting.take().filter(|_| woken) {
            let _ = accepting.join();
        }
    }
}

fn accept_loop(listener: &TcpListener, settings: &Settings, latest: &Latest, stop: &AtomicBool) {
    let active = Arc::new(AtomicUsize::new(0));
    for stream in listener.incoming() {
        if stop.load(Ordering::Acquire) {
            return;
        }
        let Ok(stream) = stream else {
            // Out of descriptors and the like: let the moment pass.
            thread::sleep(Duration::from_millis(10));
            continue;
        };
        let (allowed, loopback) = {
            let endpoint = settings.lock().unwrap_or_else(PoisonError::into_inner);
            let allowed = stream.peer_addr().is_ok_and(|p| endpoint.allows(p.ip()));
            (allowed, endpoint.address.is_loopback())
        };
        if !allowed || active.load(Ordering::Acquire) >= MAX_CONNECTIONS {
            continue; // dropped: closed unanswered
        }
        active.fetch_add(1, Ordering::AcqRel);
        let (count, latest) = (active.clone(), latest.clone());
        let spawned = thread::Builder::new()
            .name("stats-conn".into())
            .spawn(move || {
                serve(stream, &latest, loopback);
                count.fetch_sub(1, Ordering::AcqRel);
            });
        if spawned.is_err() {
            // No thread: the connection was closed unanswered; its place is free again.
            active.fetch_sub(1, Ordering::AcqRel);
        }
    }
}

/// Reads one request head and answers it, within the deadlines.
fn serve(mut stream: TcpStream, latest: &Latest, loopback: bool) {
    let _ = stream.set_nodelay(true);
    let Some(head) = read_head(&mut stream) else {
        return;
    };
    let snapshot = latest
        .lock()
        .unwrap_or_else(PoisonError::into_inner)
        .clone();
    let answer = respond(&head, &snapshot, loopback);
    let deadline = Instant::now() + DEADLINE;
    let mut rest = &answer[..];
    while !rest.is_empty() {
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() || stream.set_write_timeout(Some(left)).is_err() {
            return;
        }
        match stream.write(rest) {
            Ok(0) => return,
            Ok(n) => rest = &rest[n..],
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(_) => return,
        }
    }
    let _ = stream.flush();
    linger(&mut stream, deadline);
}

/// Ends the answer with a FIN and reads (and drops) what the client still sends until
/// it closes its side, at most until `deadline`: closing a socket with unread input
/// makes the kernel send a reset, which throws away the part of the answer the client
/// has not taken yet (a request with a body, a second request behind the first).
fn linger(stream: &mut TcpStream, deadline: Instant) {
    if stream.shutdown(std::net::Shutdown::Write).is_err() {
        return;
    }
    let mut scratch = [0u8; 1024];
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() || stream.set_read_timeout(Some(left)).is_err() {
            return;
        }
        match stream.read(&mut scratch) {
            Ok(0) => return,
            Ok(_) => {}
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(_) => return,
        }
    }
}

/// Where the request head in `bytes` ends (just after its blank line), if it is whole:
/// its lines ended by CRLF or by a bare LF (which RFC 9112 lets a server accept).
fn head_end(bytes: &[u8]) -> Option<usize> {
    let crlf = bytes
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .map(|i| i + 4);
    let lf = bytes.windows(2).position(|w| w == b"\n\n").map(|i| i + 2);
    match (crlf, lf) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    }
}

/// The request head (up to the blank line, or whatever arrived by the deadline or before
/// the client stopped sending, or [`MAX_HEAD`] bytes and one more when no blank line
/// came within them); `None` if nothing arrived. What came after the blank line (a
/// pipelined request) is not part of it. An incomplete head is answered as a bad
/// request.
fn read_head(stream: &mut TcpStream) -> Option<Vec<u8>> {
    let deadline = Instant::now() + DEADLINE;
    let mut head = Vec::with_capacity(1024);
    let mut chunk = [0u8; 1024];
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() || stream.set_read_timeout(Some(left)).is_err() {
            break;
        }
        let n = match stream.read(&mut chunk) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
            Err(_) => break,
        };
        // Only the bytes that may still end a head are kept: three of the last chunk
        // (a blank line split between chunks), and up to one past the limit.
        let from = head.len().saturating_sub(3);
        let room = MAX_HEAD + 1 - head.len().min(MAX_HEAD + 1);
        head.extend_from_slice(&chunk[..n.min(room)]);
        if let Some(end) = head_end(&head[from..]) {
            head.truncate(from + end);
            return Some(head);
        }
        if head.len() > MAX_HEAD {
            return Some(head);
        }
    }
    (!head.is_empty()).then_some(head)
}

/// The whole answer (status line, headers, body) to the request head `head`, from
/// `snapshot`; with `loopback` (the endpoint listens on a loopback address), 403 unless
/// every `Host` the request names is this machine. Pure: no I/O, never panics, and
/// bounded by the snapshot's size.
pub fn respond(head: &[u8], snapshot: &StatsSnapshot, loopback: bool) -> Vec<u8> {
    if head.len() > MAX_HEAD {
        return answer(
            431,
            "text/plain; charset=utf-8",
            b"request head too large\n",
        );
    }
    let mut headers = [httparse::EMPTY_HEADER; MAX_HEADERS];
    let mut request = httparse::Request::new(&mut headers);
    match request.parse(head) {
        Ok(httparse::Status::Complete(_)) => {}
        Err(httparse::Error::TooManyHeaders) => {
            return answer(
                431,
                "text/plain; charset=utf-8",
                b"too many header fields\n",
            );
        }
        Ok(httparse::Status::Partial) | Err(_) => {
            return answer(400, "text/plain; charset=utf-8", b"bad request\n");
        }
    }
    if loopback
        && !request
            .headers
            .iter()
            .filter(|h| h.name.eq_ignore_ascii_case("host"))
            .all(|h| names_this_machine(h.value))
    {
        return answer(
            403,
            "text/plain; charset=utf-8",
            b"this endpoint answers requests for this machine only (Host: 127.0.0.1, [::1] or localhost)\n",
        );
    }
    let bodyless = match request.method {
        Some("GET") => false,
        Some("HEAD") => true,
        _ => return answer(405, "text/plain; charset=utf-8", b"only GET and HEAD\n"),
    };
    let target = origin_path(request.path.unwrap_or("/"));
    let target = target.split('#').next().unwrap_or(target);
    let (path, query) = target.split_once('?').unwrap_or((target, ""));
    let mut out = match path {
        "/metrics" => answer(
            200,
            stats::prometheus::CONTENT_TYPE,
            stats::prometheus::render(snapshot).as_bytes(),
        ),
        "/stats" => answer(
            200,
            "application/json",
            stats::json::render(&HistoryQuery::parse(query).apply(snapshot)).as_bytes(),
        ),
        "/" | "/index.html" => answer(
            200,
            "text/html; charset=utf-8",
            stats::STATUS_PAGE.as_bytes(),
        ),
        _ => answer(404, "text/plain; charset=utf-8", b"not found\n"),
    };
    if bodyless {
        // HEAD: the same status and headers (Content-Length included), no body.
        let end = out
            .windows(4)
            .position(|w| w == b"\r\n\r\n")
            .map_or(out.len(), |i| i + 4);
        out.truncate(end);
    }
    out
}

/// Whether a `Host` value names this machine: an IP address (a name that only resolves
/// to one could be any site's), or `localhost`, with or without a port.
fn names_this_machine(host: &[u8]) -> bool {
    let Ok(host) = std::str::from_utf8(host) else {
        return false;
    };
    let host = host.trim();
    let name = match host.strip_prefix('[') {
        // `[::1]:9100`
        Some(rest) => {
            return rest.split_once(']').is_some_and(|(address, port)| {
                address.parse::<std::net::Ipv6Addr>().is_ok()
                    && (port.is_empty()
                        || port
                            .strip_prefix(':')
                            .is_some_and(|p| p.bytes().all(|b| b.is_ascii_digit())))
            });
        }
        None => match host.rsplit_once(':') {
            Some((name, port)) if port.bytes().all(|b| b.is_ascii_digit()) => name,
            _ => host,
        },
    };
    let name = name.strip_suffix('.').unwrap_or(name);
    name.parse::<std::net::Ipv4Addr>().is_ok() || name.eq_ignore_ascii_case("localhost")
}

/// The path of a request target: the target itself in origin form (`/stats`), the part
/// after the authority in absolute form (`http://127.0.0.1:9100/stats`, which servers
/// must accept: RFC 9112 §3.2.2), `/` when that part is empty.
fn origin_path(target: &str) -> &str {
    let Some((scheme, rest)) = target.split_once("://") else {
        return target;
    };
    if !scheme.eq_ignore_ascii_case("http") && !scheme.eq_ignore_ascii_case("https") {
        return target;
    }
    match rest.find(['/', '?']) {
        Some(i) if rest[i..].starts_with('/') => &rest[i..],
        _ => "/",
    }
}

fn answer(status: u16, content_type: &str, body: &[u8]) -> Vec<u8> {
    let reason = match status {
        200 => "OK",
        400 => "Bad Request",
        404 => "Not Found",
        403 => "Forbidden",
        405 => "Method Not Allowed",
        431 => "Request Header Fields Too Large",
        _ => "Error",
    };
    let allow = if status == 405 {
        "Allow: GET, HEAD\r\n"
    } else {
        ""
    };
    let mut out = format!(
        "HTTP/1.1 {status} {reason}\r\nContent-Type: {content_type}\r\nContent-Length: {}\r\nCache-Control: no-store\r\n{allow}Connection: close\r\n\r\n",
        body.len()
    )
    .into_bytes();
    out.extend_from_slice(body);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn status(head: &[u8]) -> String {
        let a = respond(head, &StatsSnapshot::default(), true);
        String::from_utf8_lossy(&a)
            .lines()
            .next()
            .unwrap_or("")
            .to_string()
    }

    /// What `read_head` makes of `bytes`, sent at once by a client that then waits.
    fn head_read_from(bytes: &[u8]) -> Option<Vec<u8>> {
        let listener = TcpListener::bind("127.0.0.1:0").expect("bind");
        let mut client = TcpStream::connect(listener.local_addr().expect("addr")).expect("connect");
        client.write_all(bytes).expect("write");
        let (mut served, _) = listener.accept().expect("accept");
        read_head(&mut served)
    }

    #[test]
    fn a_head_near_the_limit_is_read_apart_from_the_request_behind_it() {
        let first = format!(
            "GET /metrics HTTP/1.1\r\nHost: localhost\r\nX-Pad: {}\r\n\r\n",
            "p".repeat(MAX_HEAD - 100)
        );
        let both = [
            first.as_bytes(),
            b"GET / HTTP/1.1\r\n\r\n".repeat(60).as_slice(),
        ]
        .concat();
        let head = head_read_from(&both).expect("a head");
        assert_eq!(head, first.as_bytes());
        assert_eq!(status(&head), "HTTP/1.1 200 OK");
        // A head with no end within the limit is still refused.
        let long = format!("GET / HTTP/1.1\r\nX-Pad: {}\r\n\r\n", "p".repeat(MAX_HEAD));
        let head = head_read_from(long.as_bytes()).expect("bytes");
        assert_eq!(head.len(), MAX_HEAD + 1);
        assert_eq!(
            status(&head),
            "HTTP/1.1 431 Request Header Fields Too Large"
        );
    }

    #[test]
    fn routes_and_errors() {
        assert_eq!(
            status(b"GET /metrics HTTP/1.1\r\nHost: localhost:9100\r\n\r\n"),
            "HTTP/1.1 200 OK"
        );
        assert_eq!(
            status(b"GET /stats?x=1 HTTP/1.0\r\n\r\n"),
            "HTTP/1.1 200 OK"
        );
        assert_eq!(status(b"GET / HTTP/1.1\r\n\r\n"), "HTTP/1.1 200 OK");
        assert_eq!(
            status(b"GET /nope HTTP/1.1\r\n\r\n"),
            "HTTP/1.1 404 Not Found"
        );
        assert_eq!(
            status(b"POST /stats HTTP/1.1\r\n\r\n"),
            "HTTP/1.1 405 Method Not Allowed"
        );
        assert_eq!(
            status(b"GET /stats HTTP/1.1\r\n"),
            "HTTP/1.1 400 Bad Request"
        );
        assert_eq!(
            status(b"\x00\xff garbage\r\n\r\n"),
            "HTTP/1.1 400 Bad Request"
        );
        assert_eq!(
            status(b"GET http://127.0.0.1:9100/stats HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n"),
            "HTTP/1.1 200 OK"
        );
        assert_eq!(
            status(b"GET HTTP://localhost?x HTTP/1.1\r\n\r\n"),
            "HTTP/1.1 200 OK"
        );
        assert_eq!(
            status(b"GET http://127.0.0.1:9100/nope HTTP/1.1\r\n\r\n"),
            "HTTP/1.1 404 Not Found"
        );
        let big = vec![b'a'; MAX_HEAD + 1];
        assert_eq!(status(&big), "HTTP/1.1 431 Request Header Fields Too Large");
    }

    #[test]
    fn head_answers_like_get_without_a_body() {
        let snapshot = StatsSnapshot::default();
        for path in ["/stats", "/metrics", "/", "/nope"] {
            let get = respond(
                format!("GET {path} HTTP/1.1\r\n\r\n").as_bytes(),
                &snapshot,
                true,
            );
            let head = respond(
                format!("HEAD {path} HTTP/1.1\r\n\r\n").as_bytes(),
                &snapshot,
                true,
            );
            let end = get
                .windows(4)
                .position(|w| w == b"\r\n\r\n")
                .expect("a head")
                + 4;
            assert!(get.len() > end, "{path}: GET has a body");
            assert_eq!(head, get[..end], "{path}");
        }
    }

    #[test]
    fn on_loopback_only_requests_for_this_machine_are_answered() {
        let ask = |host: &str, loopback: bool| {
            let head = format!("GET /stats HTTP/1.1\r\nHost: {host}\r\n\r\n");
            let a = respond(head.as_bytes(), &StatsSnapshot::default(), loopback);
            String::from_utf8_lossy(&a[..12]).to_string()
        };
        for host in [
            "127.0.0.1",
            "127.0.0.1:9100",
            "[::1]:9100",
            "[::1]",
            "localhost",
            "LocalHost:9100",
            "localhost.",
            "192.168.1.20:9100",
        ] {
            assert_eq!(ask(host, true), "HTTP/1.1 200", "{host}");
        }
        for host in [
            "evil.example",
            "evil.example:9100",
            "localhost.evil.example",
            "[::1",
            "",
        ] {
            assert_eq!(ask(host, true), "HTTP/1.1 403", "{host}");
            assert_eq!(ask(host, false), "HTTP/1.1 200", "{host}, not on loopback");
        }
        // Two Host fields: both must name this machine.
        let two = b"GET /stats HTTP/1.1\r\nHost: 127.0.0.1\r\nHost: evil.example\r\n\r\n";
        assert!(respond(two, &StatsSnapshot::default(), true).starts_with(b"HTTP/1.1 403"));
    }
}
