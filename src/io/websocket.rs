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
//! - A connection closed for an error still tells the peer why: the loop lets it
//!   linger ([`Driver::parting`]) until the peer, which gets the answer or the Close
//!   frame and then the end, ends too (see [`Until`]); what it still sends meanwhile is
//!   read and dropped. Closed at once, with the peer's bytes unread, it would be reset,
//!   and the reset may discard the answer or make the peer fail in the middle of a
//!   send, before reading it.
//! - Output is taken from the core a few frames at a time, only once what was taken
//!   before has been written: a client that never reads is held back by the core's
//!   per-link queue, as a TCP client is; the driver never buffers more.
//!
//! Framing, masking, ping/pong and the closing handshake are `tungstenite`'s.

use std::collections::VecDeque;
use std::io;
use std::io::{Read, Write};
use std::net::{Shutdown, SocketAddr, TcpStream};
use std::os::fd::{AsRawFd, RawFd};
use std::rc::Rc;
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
use super::tcp::{self, Input, TcpListenerDriver};
use crate::config::WebSocketInterface;
use crate::routing::{Engine, InterfaceId, Timestamp, Transmit};

/// The largest message (and frame) taken from a client; a larger one closes it.
pub const MAX_MESSAGE: usize = 64 * 1024;
/// How long a connection may take to complete its handshake.
pub const HANDSHAKE_LIMIT: Duration = Duration::from_secs(5);
/// Messages read per wake-up before the loop gets a turn to send.
const READS_PER_TURN: usize = 16;
/// Bytes read per wake-up at most, whatever they hold (see [`Socket`]).
const READ_BUDGET: usize = 64 * 1024;
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

/// The connection's socket as tungstenite holds it. The driver keeps a handle of its
/// own: a failed handshake consumes tungstenite's, and the driver still answers and
/// ends the connection on the socket, whose descriptor the loop watches.
///
/// While a turn reads messages, its reads are held to a budget of bytes: tungstenite's
/// `read` returns only with a whole message or when the socket has nothing more, so a
/// peer that streams frames which never end a message (empty continuation frames
/// grow no message) would otherwise keep the loop in one call for as long as it sends.
/// Once the budget is spent a read answers "would block", and the turn ends with more
/// to read.
struct Socket {
    stream: Rc<TcpStream>,
    /// Bytes the current turn may still read (`None`: no turn is counting).
    budget: Option<usize>,
    /// A read was refused because the budget was spent.
    spent: bool,
}

impl Socket {
    fn new(stream: Rc<TcpStream>) -> Self {
        Socket {
            stream,
            budget: None,
            spent: false,
        }
    }
}

impl Read for Socket {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let Some(left) = self.budget else {
            return (&*self.stream).read(buf);
        };
        if left == 0 {
            self.spent = true;
            return Err(io::ErrorKind::WouldBlock.into());
        }
        let n = buf.len().min(left);
        let got = (&*self.stream).read(&mut buf[..n])?;
        self.budget = Some(left - got);
        Ok(got)
    }
}

impl Write for Socket {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        (&*self.stream).write(buf)
    }

    fn flush(&mut self) -> io::Result<()> {
        (&*self.stream).flush()
    }
}

/// Queues a Close frame of `code` saying why the connection ends; it goes out with the
/// next flush.
fn start_close(ws: &mut WebSocket<Socket>, code: CloseCode, reason: &'static str) {
    let frame = CloseFrame {
        code,
        reason: Utf8Bytes::from_static(reason),
    };
    let _ = ws.close(Some(frame));
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
    Accepted(Rc<TcpStream>, OriginCheck),
    /// The HTTP upgrade is under way (with the driver's handle on the socket).
    Handshake(
        MidHandshake<ServerHandshake<Socket, OriginCheck>>,
        Rc<TcpStream>,
    ),
    /// Messages flow.
    Open(WebSocket<Socket>),
    /// Its Close frame waits in tungstenite's buffer for room in the socket: the
    /// sending side is shut once it is out. What the peer sends meanwhile is read and
    /// dropped.
    Closing(WebSocket<Socket>, Until),
    /// The sending side is shut: what the peer still sends is read and dropped until it
    /// may close.
    Shut(Rc<TcpStream>, Until),
    /// Closed, or its handshake failed.
    Gone,
}

/// When a connection whose sending side is shut may close (within the loop's limit).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Until {
    /// Once everything sent is acknowledged, even if the peer still sends (at shutdown,
    /// after a reload removed the block, or after the peer's own Close).
    Acknowledged,
    /// Once the peer ends: after an HTTP error answer, whose request may still have a
    /// body on its way, and after a Close for an error, as the peer may still be sending
    /// the message that caused it (blocked until its bytes are read). A peer that read
    /// the answer or the Close, and then the end, ends too.
    Ended,
}

impl Until {
    /// Reads and drops what the peer sent since the last look; true once `socket` may
    /// close.
    fn reached(self, socket: &TcpStream) -> bool {
        match (self, tcp::drain(socket)) {
            (_, Input::Ended | Input::Failed) => true,
            (Until::Ended, Input::Open) => false,
            (Until::Acknowledged, Input::Open) => tcp::all_acknowledged(socket),
        }
    }
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
            state: State::Accepted(Rc::new(stream), check),
            deadline: Some(now + HANDSHAKE_LIMIT),
            unflushed: false,
            failed: None,
            next: VecDeque::with_capacity(FRAMES_PER_WRITE),
        }
    }

    /// Drives the handshake: `Done` while it is under way (or once it is done and the
    /// first messages read), `Lost` if it failed.
    fn handshake(&mut self, engine: &mut Engine, now: Timestamp) -> Progress {
        let (result, socket) = match std::mem::replace(&mut self.state, State::Gone) {
            State::Accepted(socket, check) => {
                let theirs = Socket::new(Rc::clone(&socket));
                let result = tungstenite::accept_hdr_with_config(theirs, check, Some(ws_config()));
                (result, socket)
            }
            State::Handshake(mid, socket) => (mid.handshake(), socket),
            other => {
                self.state = other;
                return Progress::Done;
            }
        };
        match result {
            Ok(ws) => {
                self.state = State::Open(ws);
                self.deadline = None;
                // What the core queued for it can go now; messages may have come
                // with the request.
                engine.stream_opened(self.interface, now);
                self.read(engine, now)
            }
            Err(HandshakeError::Interrupted(mid)) => {
                self.state = State::Handshake(mid, socket);
                Progress::Done
            }
            // tungstenite has answered 403.
            Err(HandshakeError::Failure(WsError::Http(r)))
                if r.status() == StatusCode::FORBIDDEN =>
            {
                let why =
                    "WebSocket handshake refused: the page's origin is not one the block allows";
                self.report(engine, now, Some(why.to_string()));
                self.refused(socket)
            }
            Err(HandshakeError::Failure(e)) => match refusal(&e) {
                Some((status, text)) => {
                    // A few hundred bytes into an empty send buffer.
                    let _ = (&*socket).write_all(text.as_bytes());
                    let why = format!("WebSocket handshake failed: {e} (answered {status})");
                    self.report(engine, now, Some(why));
                    self.refused(socket)
                }
                None => self.lose(
                    engine,
                    now,
                    Some(format!("WebSocket handshake failed: {e}")),
                ),
            },
        }
    }

    /// Ends a connection whose request was answered with an HTTP error: the end follows
    /// the answer, and the loop lets it linger until the peer ends too.
    fn refused(&mut self, socket: Rc<TcpStream>) -> Progress {
        self.deadline = None;
        self.state = match socket.shutdown(Shutdown::Write) {
            Ok(()) => State::Shut(socket, Until::Ended),
            Err(_) => State::Gone,
        };
        Progress::Lost
    }

    /// Ends an open connection for an error (reported to the core): a Close frame of
    /// `code` says why, and what of it the socket does not take now goes out while the
    /// loop lets the connection linger.
    fn part(
        &mut self,
        engine: &mut Engine,
        now: Timestamp,
        (code, reason): (CloseCode, &'static str),
        why: String,
    ) -> Progress {
        self.report(engine, now, Some(why));
        self.close_open(Some((code, reason)), Until::Ended);
        Progress::Lost
    }

    /// Takes an open connection to [`State::Closing`], a Close frame of `close` queued if
    /// given; what is queued goes out as far as the socket takes it now, the rest while
    /// it lingers. Any other state is gone.
    fn close_open(&mut self, close: Option<(CloseCode, &'static str)>, until: Until) {
        self.state = match std::mem::replace(&mut self.state, State::Gone) {
            State::Open(mut ws) => {
                if let Some((code, reason)) = close {
                    start_close(&mut ws, code, reason);
                }
                let _ = ws.flush();
                State::Closing(ws, until)
            }
            _ => State::Gone,
        };
    }

    /// Reports the connection lost, and closes it: an error (logged and counted) or a
    /// normal end.
    fn lose(&mut self, engine: &mut Engine, now: Timestamp, error: Option<String>) -> Progress {
        self.state = State::Gone;
        self.report(engine, now, error);
        Progress::Lost
    }

    /// Tells the core the connection is lost: an error (logged and counted) or a normal
    /// end.
    fn report(&mut self, engine: &mut Engine, now: Timestamp, error: Option<String>) {
        match error {
            Some(why) => {
                engine.on_stream_failed(self.interface, &why);
                engine.stream_lost(self.interface, now, &why);
            }
            None => engine.stream_lost(self.interface, now, &"closed"),
        }
    }

    /// Reads what an open connection has: a bounded number of messages, and of bytes
    /// (see [`Socket`]); `More` when a bound ended the turn.
    fn read(&mut self, engine: &mut Engine, now: Timestamp) -> Progress {
        self.count_reads(Some(READ_BUDGET));
        let progress = self.read_messages(engine, now);
        let spent = self.count_reads(None);
        match progress {
            Progress::Done if spent => Progress::More,
            other => other,
        }
    }

    /// Starts (`Some`) or ends (`None`) a turn's budget of bytes read; whether the turn
    /// that ends spent it.
    fn count_reads(&mut self, budget: Option<usize>) -> bool {
        let (State::Open(ws) | State::Closing(ws, _)) = &mut self.state else {
            return false;
        };
        let socket = ws.get_mut();
        socket.budget = budget;
        std::mem::take(&mut socket.spent)
    }

    /// Reads up to [`READS_PER_TURN`] messages.
    fn read_messages(&mut self, engine: &mut Engine, now: Timestamp) -> Progress {
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
                // tungstenite queued the reply. A code that says something went wrong
                // is an error (said, counted); tungstenite gives a code the protocol
                // does not allow as 1002, which it answers too. Application codes
                // (3000–4999) are the page's own business.
                Ok(Message::Close(frame)) => {
                    if let Some(f) = frame.filter(|f| {
                        matches!(
                            f.code,
                            CloseCode::Protocol
                                | CloseCode::Unsupported
                                | CloseCode::Invalid
                                | CloseCode::Policy
                                | CloseCode::Size
                                | CloseCode::Extension
                                | CloseCode::Error
                                | CloseCode::Bad(_)
                                | CloseCode::Reserved(_)
                        )
                    }) {
                        let why = format!(
                            "closed by the peer with code {}: {}",
                            u16::from(f.code),
                            f.reason.as_str().escape_debug()
                        );
                        engine.on_stream_failed(id, &why);
                    }
                    return self.end(engine, now, true);
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
                ) => return self.end(engine, now, false),
                Err(WsError::Capacity(e)) => {
                    let why = format!("message over {MAX_MESSAGE} bytes: {e}");
                    return self.part(engine, now, (CloseCode::Size, "message over 64 KiB"), why);
                }
                Err(e @ WsError::Protocol(_)) => {
                    let close = (CloseCode::Protocol, "protocol error");
                    return self.part(engine, now, close, e.to_string());
                }
                Err(e @ WsError::Utf8(_)) => {
                    let close = (CloseCode::Invalid, "text not UTF-8");
                    return self.part(engine, now, close, e.to_string());
                }
                Err(e) => return self.lose(engine, now, Some(e.to_string())),
            }
        }
        Progress::More
    }

    /// The peer ended the connection: a failed write is what is reported, if any. With
    /// `reply`, it sent a Close frame, and the reply tungstenite queued goes out while
    /// the connection lingers.
    fn end(&mut self, engine: &mut Engine, now: Timestamp, reply: bool) -> Progress {
        if let Some(e) = self.failed.take() {
            return self.lose(engine, now, Some(format!("send failed: {e}")));
        }
        self.report(engine, now, None);
        if reply {
            self.close_open(None, Until::Acknowledged);
        } else {
            self.state = State::Gone;
        }
        Progress::Lost
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
        self.deadline = None;
        self.unflushed = false;
        self.failed = None;
    }

    fn receive(&mut self, engine: &mut Engine, now: Timestamp) -> Progress {
        match self.state {
            State::Accepted(..) | State::Handshake(..) => self.handshake(engine, now),
            State::Open(_) => self.read(engine, now),
            State::Closing(..) | State::Shut(..) | State::Gone => Progress::Done,
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
                _ => return Progress::Done,
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
                        // This frame and the ones taken with it go with the
                        // connection; its loss is counted once, when reported.
                        engine.on_stream_frame_lost(&t);
                        for t in self.next.drain(..) {
                            engine.on_stream_frame_lost(&t);
                        }
                        self.failed = Some(io::Error::other(e.to_string()));
                        return Progress::Blocked;
                    }
                }
            }
            self.unflushed = true;
        }
    }

    fn idle(&self) -> bool {
        !(self.unflushed && matches!(self.state, State::Open(_)))
    }

    fn shut_write(&mut self) -> bool {
        match std::mem::replace(&mut self.state, State::Gone) {
            State::Open(mut ws) => {
                start_close(&mut ws, CloseCode::Away, "the router closes this link");
                self.state = State::Closing(ws, Until::Acknowledged);
                true
            }
            other => {
                self.state = other;
                self.parting()
            }
        }
    }

    fn parting(&self) -> bool {
        matches!(self.state, State::Closing(..) | State::Shut(..))
    }

    fn linger(&mut self) -> bool {
        match &mut self.state {
            State::Closing(ws, until) => {
                // A peer blocked in a send reads the Close only once that send is done.
                // One that ended its sending side may still read: the Close still goes.
                if tcp::drain(&ws.get_ref().stream) == Input::Failed {
                    return true;
                }
                match ws.flush() {
                    // Out (the latter once a Close from the peer is answered).
                    Ok(()) | Err(WsError::ConnectionClosed) => {}
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
                let socket = Rc::clone(&ws.get_ref().stream);
                if socket.shutdown(Shutdown::Write).is_err() {
                    return true;
                }
                // Looked at from the next call on: input has just been drained.
                self.state = State::Shut(socket, *until);
                false
            }
            State::Shut(socket, until) => until.reached(socket),
            _ => true,
        }
    }

    fn deadline(&self) -> Option<Timestamp> {
        self.deadline
    }

    fn expire(&mut self, engine: &mut Engine, now: Timestamp) -> Progress {
        if !matches!(self.state, State::Accepted(..) | State::Handshake(..)) {
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
