//! The drivers of one `websocket { }` interface: a TCP listening socket (the `tcp`
//! server's, see [`TcpListenerDriver::listen`]) whose every accepted connection gets a
//! [`WebSocketDriver`]: the HTTP upgrade, then MAVLink in binary WebSocket messages.
//!
//! - The router sends one whole frame per binary message.
//! - What it receives in binary messages is one byte stream: a message may hold several
//!   frames, and a frame may be split across messages.
//! - Text messages are not MAVLink: their bytes are counted as junk and dropped; the
//!   connection stays.
//! - A message (or frame) over [`MAX_MESSAGE`] bytes (Close code 1009), a protocol
//!   error (1002), or a handshake not done within
//!   [`HANDSHAKE_LIMIT`], closes the connection (logged, counted as an I/O error); so
//!   does a browser's request from an origin the block does not name (answered 403),
//!   and a request that is not a WebSocket upgrade (answered 426, 405 or 400: see
//!   [`refusal`]).
//! - Output is taken from the core a few frames at a time, only once what was taken
//!   before has been written: a client that never reads is held back by the core's
//!   per-link queue, as a TCP client is; the driver never buffers more.
//!
//! Framing, masking, ping/pong and the closing handshake are `tungstenite`'s.

use std::collections::VecDeque;
use std::io;
use std::io::Write;
use std::net::{Shutdown, SocketAddr, TcpStream};
use std::os::fd::{AsRawFd, RawFd};
use std::sync::Arc;
use std::time::Duration;

use tungstenite::error::{Error as WsError, ProtocolError};
use tungstenite::handshake::server::{Callback, ErrorResponse, Request, Response, ServerHandshake};
use tungstenite::handshake::{HandshakeError, MidHandshake};
use tungstenite::http::StatusCode;
use tungstenite::protocol::WebSocketConfig;
use tungstenite::protocol::frame::CloseFrame;
use tungstenite::protocol::frame::coding::CloseCode;
use tungstenite::{Message, Utf8Bytes, WebSocket};

use super::driver::{Driver, Progress};
use super::tcp::TcpListenerDriver;
use crate::config::WebSocketInterface;
use crate::routing::{Engine, InterfaceId, Timestamp, Transmit};

/// The largest message (and frame) taken from a client; a larger one closes it.
pub const MAX_MESSAGE: usize = 64 * 1024;
/// How long a connection may take to complete its handshake.
pub const HANDSHAKE_LIMIT: Duration = Duration::from_secs(5);
/// Messages read per wake-up before the loop gets a turn to send.
const READS_PER_TURN: usize = 16;
/// Frames taken from the core per write (each its own message), written out before
/// more are taken.
const FRAMES_PER_WRITE: usize = 16;

/// A `websocket` server's listening socket.
pub fn listener(
    config: &WebSocketInterface,
    interface: InterfaceId,
) -> io::Result<TcpListenerDriver> {
    let local = SocketAddr::new(config.local_address(), config.port);
    let origins: Arc<[String]> = config.origins.clone().into();
    TcpListenerDriver::listen(
        local,
        &config.label(),
        interface,
        Box::new(move |id, stream, now| {
            let check = OriginCheck(Arc::clone(&origins));
            Box::new(WebSocketDriver::accepted(id, stream, now, check))
        }),
    )
}

/// The block's `origin` statements, checked against a request's `Origin` header.
struct OriginCheck(Arc<[String]>);

impl Callback for OriginCheck {
    /// Refuses (403) a request whose `Origin` is not one of the block's, or that has
    /// more than one (a browser sends one; two could pass an allowed one beside the
    /// real one); takes any request when the block names none, and requests without
    /// the header (not made by a web page).
    fn on_request(self, request: &Request, response: Response) -> Result<Response, ErrorResponse> {
        let mut origins = request.headers().get_all("origin").iter();
        let Some(origin) = origins.next() else {
            return Ok(response);
        };
        let allowed = self.0.is_empty()
            || (origins.next().is_none()
                && origin
                    .to_str()
                    .is_ok_and(|o| self.0.iter().any(|a| a.eq_ignore_ascii_case(o))));
        if allowed {
            return Ok(response);
        }
        let mut refusal = ErrorResponse::new(Some("origin not allowed\n".into()));
        *refusal.status_mut() = StatusCode::FORBIDDEN;
        Err(refusal)
    }
}

/// Queues a Close frame of `code` saying why the connection ends; it goes out with the
/// next flush.
fn start_close(ws: &mut WebSocket<TcpStream>, code: CloseCode, reason: &'static str) {
    let frame = CloseFrame {
        code,
        reason: Utf8Bytes::from_static(reason),
    };
    let _ = ws.close(Some(frame));
}

/// Tells the peer why its connection ends, with a Close frame of `code` (sent as far as
/// the socket takes it now: the connection is closed next either way).
fn say_close(ws: &mut WebSocket<TcpStream>, code: CloseCode, reason: &'static str) {
    start_close(ws, code, reason);
    let _ = ws.flush();
}

/// The HTTP answer to a request the handshake refused, with its status: 426 (with
/// `Upgrade: websocket` and the version this server speaks) to a request that is not an
/// upgrade — a browser opening the port as a page — or asks for another WebSocket
/// version; 405 to another method; 400 to anything else that is not a valid upgrade
/// request. `None` when no request was refused (the connection failed or closed, or
/// the origin check answered already). The 405 has no body: it may answer a `HEAD`,
/// whose answer must have none.
fn refusal(e: &WsError) -> Option<(&'static str, String)> {
    const BODY: &str = "This port speaks WebSocket: MAVLink frames in binary messages.\n";
    let (status, headers, body) = match e {
        WsError::Protocol(
            ProtocolError::MissingUpgradeWebSocketHeader
            | ProtocolError::MissingConnectionUpgradeHeader,
        ) => (
            "426 Upgrade Required",
            "Upgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Version: 13\r\n",
            BODY,
        ),
        WsError::Protocol(ProtocolError::MissingSecWebSocketVersionHeader) => (
            "426 Upgrade Required",
            "Sec-WebSocket-Version: 13\r\n",
            BODY,
        ),
        WsError::Protocol(ProtocolError::WrongHttpMethod) => {
            ("405 Method Not Allowed", "Allow: GET\r\n", "")
        }
        // The peer ended before its request was whole (a port scan, a health check).
        WsError::Protocol(ProtocolError::HandshakeIncomplete)
        | WsError::Io(_)
        | WsError::ConnectionClosed
        | WsError::AlreadyClosed
        | WsError::Http(_) => {
            return None;
        }
        _ => ("400 Bad Request", "", BODY),
    };
    Some((
        status,
        format!(
            "HTTP/1.1 {status}\r\n{headers}Content-Type: text/plain\r\nContent-Length: {}\r\n\
             Connection: close\r\n\r\n{body}",
            body.len()
        ),
    ))
}

fn ws_config() -> WebSocketConfig {
    WebSocketConfig::default()
        // Read in chunks of a few pages; MAVLink frames are small.
        .read_buffer_size(8 * 1024)
        // Messages wait in the buffer until `flush` (at most FRAMES_PER_WRITE frames).
        .write_buffer_size(64 * 1024)
        .max_write_buffer_size(128 * 1024)
        .max_message_size(Some(MAX_MESSAGE))
        .max_frame_size(Some(MAX_MESSAGE))
}

/// Where a connection is.
enum State {
    /// Accepted; the handshake starts at the first `receive`.
    Accepted(TcpStream, OriginCheck),
    /// The HTTP upgrade is under way.
    Handshake(MidHandshake<ServerHandshake<TcpStream, OriginCheck>>),
    /// Messages flow.
    Open(WebSocket<TcpStream>),
    /// Closed, or its handshake failed.
    Gone,
}

/// One accepted WebSocket connection: one link of the core.
pub struct WebSocketDriver {
    interface: InterfaceId,
    state: State,
    fd: RawFd,
    /// The handshake must be done by then (None once it is).
    deadline: Option<Timestamp>,
    /// Messages written to tungstenite's buffer but not yet flushed to the socket.
    unflushed: bool,
    /// A write failed: the connection is lost once what is left to read has been read.
    failed: Option<io::Error>,
    /// Scratch for [`Engine::poll_transmit`].
    next: VecDeque<Transmit>,
    /// Its Close frame (see [`Driver::shut_write`]) waits in tungstenite's buffer for
    /// room in the socket: the sending side is shut once it is out.
    closing: bool,
    /// A second handle on the socket while the handshake runs: tungstenite takes the
    /// stream and answers only what the origin check refuses, so the HTTP error for
    /// any other refused request goes out through this one.
    answer: Option<TcpStream>,
}

impl WebSocketDriver {
    /// A connection accepted at `now` as the core's interface `id`: its handshake starts.
    fn accepted(
        interface: InterfaceId,
        stream: TcpStream,
        now: Timestamp,
        check: OriginCheck,
    ) -> Self {
        WebSocketDriver {
            interface,
            fd: stream.as_raw_fd(),
            state: State::Accepted(stream, check),
            deadline: Some(now + HANDSHAKE_LIMIT),
            unflushed: false,
            failed: None,
            next: VecDeque::with_capacity(FRAMES_PER_WRITE),
            closing: false,
            answer: None,
        }
    }

    /// Drives the handshake: `Done` while it is under way (or once it is done and the
    /// first messages read), `Lost` if it failed.
    fn handshake(&mut self, engine: &mut Engine, now: Timestamp) -> Progress {
        let result = match std::mem::replace(&mut self.state, State::Gone) {
            State::Accepted(stream, check) => {
                self.answer = stream.try_clone().ok();
                tungstenite::accept_hdr_with_config(stream, check, Some(ws_config()))
            }
            State::Handshake(mid) => mid.handshake(),
            other => {
                self.state = other;
                return Progress::Done;
            }
        };
        match result {
            Ok(ws) => {
                self.state = State::Open(ws);
                self.deadline = None;
                self.answer = None;
                // What the core queued for it can go now; messages may have come
                // with the request.
                engine.stream_opened(self.interface, now);
                self.read(engine, now)
            }
            Err(HandshakeError::Interrupted(mid)) => {
                self.state = State::Handshake(mid);
                Progress::Done
            }
            Err(HandshakeError::Failure(WsError::Http(r)))
                if r.status() == StatusCode::FORBIDDEN =>
            {
                let why =
                    "WebSocket handshake refused: the page's origin is not one the block allows";
                self.lose(engine, now, Some(why.to_string()))
            }
            Err(HandshakeError::Failure(e)) => {
                let answered = match (self.answer.take(), refusal(&e)) {
                    (Some(mut answer), Some((status, text))) => {
                        // A few hundred bytes into an empty send buffer; then the end.
                        let _ = answer.write_all(text.as_bytes());
                        let _ = answer.shutdown(Shutdown::Write);
                        format!(" (answered {status})")
                    }
                    _ => String::new(),
                };
                self.lose(
                    engine,
                    now,
                    Some(format!("WebSocket handshake failed: {e}{answered}")),
                )
            }
        }
    }

    /// Reports the connection lost: an error (logged and counted) or a normal end.
    fn lose(&mut self, engine: &mut Engine, now: Timestamp, error: Option<String>) -> Progress {
        self.state = State::Gone;
        self.answer = None;
        match error {
            Some(why) => {
                engine.on_receive_failed(self.interface, &io::Error::other(why.clone()));
                engine.stream_lost(self.interface, now, &why);
            }
            None => engine.stream_lost(self.interface, now, &"closed"),
        }
        Progress::Lost
    }

    /// Reads what an open connection has (a bounded number of messages).
    fn read(&mut self, engine: &mut Engine, now: Timestamp) -> Progress {
        let id = self.interface;
        for _ in 0..READS_PER_TURN {
            let State::Open(ws) = &mut self.state else {
                return Progress::Done;
            };
            match ws.read() {
                Ok(Message::Binary(bytes)) => engine.handle_stream(id, &bytes, now),
                Ok(Message::Text(text)) => engine.stream_junk(id, text.len()),
                // Pings are answered by tungstenite; pongs need nothing.
                Ok(Message::Ping(_) | Message::Pong(_) | Message::Frame(_)) => {}
                Ok(Message::Close(_)) => {
                    // tungstenite queued the reply; send it if the socket takes it now.
                    let _ = ws.flush();
                    return self.end(engine, now);
                }
                Err(WsError::Io(e)) if e.kind() == io::ErrorKind::WouldBlock => {
                    return match self.failed.take() {
                        Some(e) => self.lose(engine, now, Some(format!("send failed: {e}"))),
                        None => Progress::Done,
                    };
                }
                Err(WsError::Io(e)) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(
                    WsError::ConnectionClosed
                    | WsError::AlreadyClosed
                    | WsError::Protocol(ProtocolError::ResetWithoutClosingHandshake),
                ) => return self.end(engine, now),
                Err(WsError::Capacity(e)) => {
                    say_close(ws, CloseCode::Size, "message over 64 KiB");
                    return self.lose(
                        engine,
                        now,
                        Some(format!("message over {MAX_MESSAGE} bytes: {e}")),
                    );
                }
                Err(e) => {
                    match &e {
                        WsError::Protocol(_) => {
                            say_close(ws, CloseCode::Protocol, "protocol error")
                        }
                        WsError::Utf8(_) => say_close(ws, CloseCode::Invalid, "text not UTF-8"),
                        _ => {}
                    }
                    return self.lose(engine, now, Some(e.to_string()));
                }
            }
        }
        Progress::More
    }

    /// The peer ended the connection: a failed write is what is reported, if any.
    fn end(&mut self, engine: &mut Engine, now: Timestamp) -> Progress {
        match self.failed.take() {
            Some(e) => self.lose(engine, now, Some(format!("send failed: {e}"))),
            None => self.lose(engine, now, None),
        }
    }
}

impl Driver for WebSocketDriver {
    fn interface(&self) -> InterfaceId {
        self.interface
    }

    fn fd(&self) -> Option<RawFd> {
        (!matches!(self.state, State::Gone)).then_some(self.fd)
    }

    fn close(&mut self) {
        self.state = State::Gone;
        self.answer = None;
        self.deadline = None;
        self.unflushed = false;
        self.failed = None;
    }

    fn receive(&mut self, engine: &mut Engine, now: Timestamp) -> Progress {
        match self.state {
            State::Accepted(..) | State::Handshake(_) => self.handshake(engine, now),
            State::Open(_) => self.read(engine, now),
            State::Gone => Progress::Done,
        }
    }

    fn flush(&mut self, engine: &mut Engine, now: Timestamp) -> Progress {
        if let Some(e) = self.failed.take() {
            return self.lose(engine, now, Some(format!("send failed: {e}")));
        }
        let id = self.interface;
        loop {
            let ws = match &mut self.state {
                State::Open(ws) => ws,
                // Frames wait in the core until the handshake is done (`receive`
                // drives it, and tells the core when it is).
                State::Accepted(..) | State::Handshake(_) | State::Gone => return Progress::Done,
            };
            if self.unflushed {
                match ws.flush() {
                    Ok(()) => self.unflushed = false,
                    Err(WsError::Io(e)) if e.kind() == io::ErrorKind::WouldBlock => {
                        return Progress::Blocked;
                    }
                    Err(WsError::Io(e)) if e.kind() == io::ErrorKind::Interrupted => continue,
                    Err(e) => {
                        // Reported once what the peer sent before has been read.
                        self.failed = Some(io::Error::other(e.to_string()));
                        self.unflushed = false;
                        return Progress::Blocked;
                    }
                }
            }
            engine.poll_transmit(id, now, FRAMES_PER_WRITE, &mut self.next);
            if self.next.is_empty() {
                return Progress::Done;
            }
            while let Some(t) = self.next.pop_front() {
                match ws.write(Message::Binary(t.packet.to_vec().into())) {
                    // Buffered (a write the socket refused stays buffered too).
                    Ok(()) => engine.on_sent(&t),
                    Err(WsError::Io(e)) if e.kind() == io::ErrorKind::WouldBlock => {
                        engine.on_sent(&t);
                    }
                    Err(e) => {
                        let e = io::Error::other(e.to_string());
                        engine.on_send_failed(id, &t, &e);
                        self.next.clear();
                        self.failed = Some(e);
                        return Progress::Blocked;
                    }
                }
            }
            self.unflushed = true;
        }
    }

    fn idle(&self) -> bool {
        !self.unflushed || matches!(self.state, State::Gone)
    }

    fn shut_write(&mut self) -> bool {
        let State::Open(ws) = &mut self.state else {
            return false;
        };
        start_close(ws, CloseCode::Away, "the router closes this link");
        self.closing = true;
        true
    }

    fn linger(&mut self) -> bool {
        let State::Open(ws) = &mut self.state else {
            return true;
        };
        if self.closing {
            match ws.flush() {
                Ok(()) => {}
                Err(WsError::Io(e))
                    if matches!(
                        e.kind(),
                        io::ErrorKind::WouldBlock | io::ErrorKind::Interrupted
                    ) =>
                {
                    return false;
                }
                Err(_) => return true,
            }
            self.closing = false;
            if ws.get_ref().shutdown(Shutdown::Write).is_err() {
                return true;
            }
        }
        super::tcp::linger_on(ws.get_mut())
    }

    fn deadline(&self) -> Option<Timestamp> {
        self.deadline
    }

    fn expire(&mut self, engine: &mut Engine, now: Timestamp) -> Progress {
        if !matches!(self.state, State::Accepted(..) | State::Handshake(_)) {
            self.deadline = None;
            return Progress::Done;
        }
        self.lose(
            engine,
            now,
            Some(format!(
                "WebSocket handshake not completed within {} s",
                HANDSHAKE_LIMIT.as_secs()
            )),
        )
    }
}
