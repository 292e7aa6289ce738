//! The one HTTP request `mavtables stats` makes: a GET over a `TcpStream`, bounded in
//! time and size, whose 200 answer's body is returned. Enough for the router's own
//! statistics endpoint; not a general HTTP client. The status line, the headers and the
//! chunk sizes are read by `httparse`.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream, ToSocketAddrs};
use std::time::{Duration, Instant};

/// The largest answer read (a router with thousands of sources stays far below it).
const MAX_RESPONSE: usize = 16 << 20;

/// `GET path` from `authority` (`HOST:PORT`, IPv6 in brackets), the whole exchange
/// within `timeout`; the body of a `200` answer, else one line saying what went wrong.
pub(crate) fn get(authority: &str, path: &str, timeout: Duration) -> Result<Vec<u8>, String> {
    let deadline = Instant::now() + timeout;
    let addrs: Vec<SocketAddr> = authority
        .to_socket_addrs()
        .map_err(|e| format!("cannot resolve {authority}: {e}"))?
        .collect();
    let mut stream = connect(authority, &addrs, deadline)?;
    let request = format!(
        "GET {path} HTTP/1.1\r\nHost: {authority}\r\nAccept: application/json\r\n\
         User-Agent: mavtables/{}\r\nConnection: close\r\n\r\n",
        env!("CARGO_PKG_VERSION")
    );
    let left = deadline.saturating_duration_since(Instant::now());
    if left.is_zero() || stream.set_write_timeout(Some(left)).is_err() {
        return Err(format!("{authority} did not answer in time"));
    }
    stream
        .write_all(request.as_bytes())
        .map_err(|e| format!("{authority}: sending the request failed: {e}"))?;
    let raw = read_all(&mut stream, deadline, authority)?;
    parse_response(&raw).map_err(|e| format!("{authority} (GET {path}): {e}"))
}

/// The first address of `addrs` that accepts a connection before `deadline` (each
/// attempt gets the time left, so one address that does not answer cannot use up the
/// time of the exchange and leave the next one none).
fn connect(authority: &str, addrs: &[SocketAddr], deadline: Instant) -> Result<TcpStream, String> {
    let mut last = None;
    for (i, addr) in addrs.iter().enumerate() {
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() {
            break;
        }
        // Addresses still to try after this one share the time with it.
        let share = left / u32::try_from(addrs.len() - i).unwrap_or(u32::MAX);
        match TcpStream::connect_timeout(addr, share) {
            Ok(s) => return Ok(s),
            Err(e) => last = Some(e),
        }
    }
    Err(match last {
        Some(e) => format!(
            "cannot connect to {authority}: {e} (is mavtables running with a stats block there?)"
        ),
        None if addrs.is_empty() => format!("cannot resolve {authority}: no address"),
        None => format!("{authority} did not answer in time"),
    })
}

/// Everything the server sends until it closes, the deadline passes or the size limit.
fn read_all(stream: &mut TcpStream, deadline: Instant, authority: &str) -> Result<Vec<u8>, String> {
    let mut raw = Vec::new();
    let mut buf = [0u8; 16 * 1024];
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return Err(format!("{authority} did not answer in time"));
        }
        let _ = stream.set_read_timeout(Some(left));
        match stream.read(&mut buf) {
            Ok(0) => return Ok(raw),
            Ok(n) => {
                raw.extend_from_slice(&buf[..n]);
                if raw.len() > MAX_RESPONSE {
                    return Err(format!(
                        "{authority}: answer larger than {MAX_RESPONSE} bytes"
                    ));
                }
                // A complete answer with a length ends the read without waiting for close.
                if let Some(len) = complete_length(&raw)
                    && raw.len() >= len
                {
                    raw.truncate(len);
                    return Ok(raw);
                }
            }
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                ) =>
            {
                return Err(format!("{authority} did not answer in time"));
            }
            Err(e) => return Err(format!("{authority}: reading the answer failed: {e}")),
        }
    }
}

/// Most headers an answer may have.
const MAX_HEADERS: usize = 32;

/// An answer's head as `httparse` read it: its status, reason, the length of the head,
/// and the two headers that say where the body ends.
struct Head {
    code: u16,
    reason: String,
    len: usize,
    content_length: Option<Result<usize, ()>>,
    chunked: bool,
}

/// The head of `raw`, `Ok(None)` while it is incomplete, `Err` if it is not HTTP/1.x.
fn head(raw: &[u8]) -> Result<Option<Head>, &'static str> {
    let mut headers = [httparse::EMPTY_HEADER; MAX_HEADERS];
    let mut response = httparse::Response::new(&mut headers);
    let len = match response.parse(raw) {
        Ok(httparse::Status::Complete(len)) => len,
        Ok(httparse::Status::Partial) => return Ok(None),
        Err(_) => return Err("not an HTTP answer"),
    };
    let value = |name: &str| {
        response
            .headers
            .iter()
            .find(|h| h.name.eq_ignore_ascii_case(name))
            .and_then(|h| std::str::from_utf8(h.value).ok())
            .map(str::trim)
    };
    let content_length = value("content-length").map(|v| v.parse::<usize>().map_err(|_| ()));
    let chunked =
        value("transfer-encoding").is_some_and(|v| v.to_ascii_lowercase().contains("chunked"));
    Ok(Some(Head {
        code: response.code.unwrap_or(0),
        reason: response.reason.unwrap_or("").to_string(),
        len,
        content_length,
        chunked,
    }))
}

/// The total length of an answer whose head is complete and names a `Content-Length`
/// (public for the fuzz target).
pub fn complete_length(raw: &[u8]) -> Option<usize> {
    let head = head(raw).ok()??;
    head.len.checked_add(head.content_length?.ok()?)
}

/// The body of a complete answer, if its status is 200 (public for the fuzz target).
pub fn parse_response(raw: &[u8]) -> Result<Vec<u8>, String> {
    let head = match head(raw) {
        Ok(Some(head)) => head,
        Ok(None) if raw.is_empty() => return Err("closed the connection without answering".into()),
        Ok(None) | Err(_) => return Err("not an HTTP answer".into()),
    };
    if head.code != 200 {
        return Err(format!("answered {} {}", head.code, head.reason)
            .trim_end()
            .to_string());
    }
    let body = &raw[head.len..];
    if head.chunked {
        return dechunk(body).ok_or_else(|| "malformed chunked answer".to_string());
    }
    match head.content_length {
        Some(Ok(len)) => body
            .get(..len)
            .map(<[u8]>::to_vec)
            .ok_or_else(|| "answer shorter than its Content-Length".to_string()),
        Some(Err(())) => Err("bad Content-Length".into()),
        None => Ok(body.to_vec()),
    }
}

/// The data of a chunked body, `None` if it is malformed or incomplete.
fn dechunk(mut body: &[u8]) -> Option<Vec<u8>> {
    let mut out = Vec::new();
    loop {
        let (at, size) = match httparse::parse_chunk_size(body).ok()? {
            httparse::Status::Complete(found) => found,
            httparse::Status::Partial => return None,
        };
        let size = usize::try_from(size).ok()?;
        body = &body[at..];
        if size == 0 {
            return Some(out);
        }
        out.extend_from_slice(body.get(..size)?);
        body = body.get(size..)?.strip_prefix(b"\r\n")?;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_address_that_does_not_answer_leaves_time_for_the_next() {
        // A listener whose backlog is full: the system drops further connection
        // attempts, which then wait for an answer that never comes.
        let full = socket2::Socket::new(socket2::Domain::IPV4, socket2::Type::STREAM, None)
            .expect("socket");
        full.bind(&SocketAddr::from(([127, 0, 0, 1], 0)).into())
            .expect("bind");
        full.listen(0).expect("listen");
        let silent = full
            .local_addr()
            .ok()
            .and_then(|a| a.as_socket())
            .expect("addr");
        let _filling: Vec<socket2::Socket> = (0..8)
            .filter_map(|_| {
                let s = socket2::Socket::new(socket2::Domain::IPV4, socket2::Type::STREAM, None)
                    .ok()?;
                s.set_nonblocking(true).ok()?;
                let _ = s.connect(&silent.into());
                Some(s)
            })
            .collect();
        let answering = std::net::TcpListener::bind("127.0.0.1:0").expect("bind");
        let there = answering.local_addr().expect("addr");
        let start = Instant::now();
        let got = connect("x", &[silent, there], start + Duration::from_secs(3));
        assert_eq!(got.ok().and_then(|s| s.peer_addr().ok()), Some(there));
        assert!(
            start.elapsed() < Duration::from_millis(2500),
            "{:?}",
            start.elapsed()
        );
    }

    #[test]
    fn answers_with_length_chunks_or_close() {
        let ok =
            b"HTTP/1.1 200 OK\r\nContent-Type: application/json\r\ncontent-length: 2\r\n\r\n{}junk";
        assert_eq!(parse_response(ok), Ok(b"{}".to_vec()));
        let chunked =
            b"HTTP/1.1 200 OK\r\nTransfer-Encoding: chunked\r\n\r\n3\r\n{\"a\r\n4;x=y\r\n\":1}\r\n0\r\n\r\n";
        assert_eq!(parse_response(chunked), Ok(b"{\"a\":1}".to_vec()));
        let closed = b"HTTP/1.0 200 OK\r\n\r\n[1]";
        assert_eq!(parse_response(closed), Ok(b"[1]".to_vec()));
        assert_eq!(complete_length(ok), Some(ok.len() - 4));
    }

    #[test]
    fn bad_answers_are_one_line_errors() {
        assert_eq!(
            parse_response(b"HTTP/1.1 404 Not Found\r\n\r\n"),
            Err("answered 404 Not Found".into())
        );
        assert_eq!(
            parse_response(b""),
            Err("closed the connection without answering".into())
        );
        assert_eq!(
            parse_response(b"SSH-2.0-OpenSSH\r\n\r\n"),
            Err("not an HTTP answer".into())
        );
        assert!(parse_response(b"HTTP/1.1 200 OK\r\nContent-Length: 9\r\n\r\n{}").is_err());
        assert!(
            parse_response(b"HTTP/1.1 200 OK\r\nTransfer-Encoding: chunked\r\n\r\nzz\r\n").is_err()
        );
        assert!(
            parse_response(
                b"HTTP/1.1 200 OK\r\nTransfer-Encoding: chunked\r\n\r\nffffffffffffffff\r\n"
            )
            .is_err()
        );
    }

    proptest::proptest! {
        /// Whatever a server sends back, the answer is a body or an error, never a panic.
        #[test]
        fn any_bytes_are_an_answer_or_an_error(
            head in proptest::sample::select(vec![
                "HTTP/1.1 200 OK\r\nContent-Length: 5\r\n\r\n",
                "HTTP/1.1 200 OK\r\nTransfer-Encoding: chunked\r\n\r\n",
                "HTTP/1.0 200 OK\r\n\r\n",
                "",
            ]),
            tail in proptest::collection::vec(proptest::prelude::any::<u8>(), 0..200),
        ) {
            let mut raw = head.as_bytes().to_vec();
            raw.extend(&tail);
            let _ = parse_response(&raw);
            let _ = complete_length(&raw);
            let _ = dechunk(&tail);
        }
    }
}
