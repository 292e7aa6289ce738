//! The driver of one `zenoh { }` interface: a Zenoh session, which runs on threads of
//! its own (Zenoh's runtime), bridged to the event loop by two bounded channels and the
//! loop's waker. The loop never waits for Zenoh: a frame that does not fit in the
//! channel to the session is dropped and counted as a send failure, a sample that does
//! not fit in the channel to the loop is dropped and counted too.
//!
//! Keys (one whole frame per sample, the frame's bytes exactly as routed):
//! `{prefix}/{destination}/{source system}/{source component}/{MESSAGE}`, where the
//! destination is the target system or `all` (no target, or target system 0) and the
//! message is its name (its decimal id when the dialect does not know it). The
//! interface is one link: Zenoh routes between its sessions itself, so what came from
//! Zenoh is never published again (the core never sends a frame back to the link it
//! came from), and the session never receives its own publications (`Locality::Remote`).
//!
//! Subscriptions: `receive all;` subscribes to `{prefix}/**`; an edge
//! (`receive addressed;`) to `{prefix}/all/**` and `{prefix}/{system}/**` for each
//! system the core reaches through its other links ([`Engine::systems_elsewhere`]),
//! updated whenever the interface sends or receives, so Zenoh filters at the
//! publisher's side and the edge receives only what is for it.

use std::collections::{HashMap, VecDeque};
use std::io;
use std::os::fd::RawFd;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, SyncSender, TryRecvError, TrySendError};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use mio::Waker;
use zenoh::Wait;
use zenoh::pubsub::Subscriber;
use zenoh::sample::{Locality, Sample};

use super::driver::{Driver, Progress};
use super::log;
use crate::config::{ZenohInterface, ZenohMode, ZenohReceive};
use crate::dialect::Dialect;
use crate::routing::{Engine, InterfaceId, SystemSet, Timestamp, Transmit};
use crate::wire::{Frame, HeaderRepr};

/// Samples waiting for the loop (about 1 MiB of frames at most).
const INBOX: usize = 4096;
/// Frames and subscription changes waiting for the session.
const OUTBOX: usize = 4096;
/// Samples handed to the core per turn before the loop serves the other drivers.
const SAMPLES_PER_TURN: usize = 256;
/// Frames taken from the core per call.
const SEND_BATCH: usize = 64;
/// How long stopping a session (a reload that removes or changes the interface, the
/// exit) may hold the loop.
const CLOSE_LIMIT: Duration = Duration::from_secs(2);

/// What the loop asks of the session's thread.
enum Command {
    /// Publish a frame under a key.
    Put(String, Vec<u8>),
    /// Subscribe to frames for exactly these systems (and broadcasts).
    Subscribe(SystemSet),
}

/// What the session's thread and its callbacks share with the loop.
struct Shared {
    waker: Arc<Waker>,
    /// A wake-up is pending since the loop last took the samples (one wake per burst).
    woken: AtomicBool,
    /// Samples dropped because the loop was behind.
    dropped_in: AtomicU64,
    /// Frames the session could not publish.
    put_errors: AtomicU64,
    /// How opening the session went, once it is known.
    opened: Mutex<Option<Result<(), String>>>,
}

impl Shared {
    /// Wakes the loop unless a wake-up is already pending.
    fn ring(&self) {
        if !self.woken.swap(true, Ordering::AcqRel) {
            let _ = self.waker.wake();
        }
    }
}

/// A Zenoh interface: one session, one link.
pub struct ZenohDriver {
    interface: InterfaceId,
    label: String,
    config: ZenohInterface,
    shared: Arc<Shared>,
    /// Samples from the session, while it runs.
    inbox: Option<Receiver<Vec<u8>>>,
    /// Commands to the session, while it runs (dropping it ends the session).
    outbox: Option<SyncSender<Command>>,
    worker: Option<Worker>,
    /// Scratch for the core's output.
    in_flight: VecDeque<Transmit>,
    /// The systems last asked for (an edge).
    subscribed: Option<SystemSet>,
    /// The router's [`Router::systems_generation`] and the time when `subscribed` was
    /// last checked against the systems reached elsewhere.
    ///
    /// [`Router::systems_generation`]: crate::routing::Router::systems_generation
    checked: Option<(u64, Timestamp)>,
    /// The session is being opened: the core hears how it went from `receive` or
    /// `flush` (the session's thread rings the waker when it knows).
    opening: bool,
    /// Frames not published because the session was behind.
    dropped_out: u64,
    /// Samples that were not exactly one MAVLink frame.
    malformed: u64,
}

impl ZenohDriver {
    /// A driver for `config`; the session is opened when the core asks.
    pub fn new(config: &ZenohInterface, interface: InterfaceId, waker: Arc<Waker>) -> Self {
        ZenohDriver {
            interface,
            label: config.label(),
            config: config.clone(),
            shared: Arc::new(Shared {
                waker,
                woken: AtomicBool::new(false),
                dropped_in: AtomicU64::new(0),
                put_errors: AtomicU64::new(0),
                opened: Mutex::new(None),
            }),
            inbox: None,
            outbox: None,
            worker: None,
            in_flight: VecDeque::new(),
            subscribed: None,
            checked: None,
            opening: false,
            dropped_out: 0,
            malformed: 0,
        }
    }

    /// Tells the session which systems to subscribe to when the set the core reaches
    /// elsewhere changed (an edge only; a full outbox tries again next time).
    fn refresh_subscriptions(&mut self, engine: &Engine, now: Timestamp) {
        if self.config.receive == ZenohReceive::All {
            return;
        }
        let Some(outbox) = &self.outbox else {
            return;
        };
        // Walking every link's addresses at every wake-up would cost the edge per frame:
        // look again when a link learned or lost an address, or a second on (addresses
        // that expire change nothing the router counts).
        let generation = engine.router().systems_generation();
        if let Some((seen, at)) = self.checked
            && seen == generation
            && now < at + RECHECK
        {
            return;
        }
        let systems = engine.systems_elsewhere(self.interface, now);
        if self.subscribed != Some(systems) {
            if outbox.try_send(Command::Subscribe(systems)).is_err() {
                return; // a full outbox: tried again at the next wake-up
            }
            self.subscribed = Some(systems);
        }
        self.checked = Some((generation, now));
    }

    /// Tells the core how opening the session went, once the session's thread knows:
    /// `Err(())` when it failed (the core tries again after its backoff).
    fn finish_open(&mut self, engine: &mut Engine, now: Timestamp) -> Result<(), ()> {
        if !self.opening {
            return Ok(());
        }
        let outcome = self
            .shared
            .opened
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .take();
        match outcome {
            None => Ok(()),
            Some(Ok(())) => {
                self.opening = false;
                engine.stream_opened(self.interface, now);
                Ok(())
            }
            Some(Err(why)) => {
                self.opening = false;
                engine.stream_open_failed(self.interface, now, &why);
                Err(())
            }
        }
    }

    /// Stops the session: its thread ends once it has taken what was sent to it.
    fn stop(&mut self) {
        self.outbox = None;
        self.inbox = None;
        self.subscribed = None;
        self.checked = None;
        self.opening = false;
        if let Some(worker) = self.worker.take()
            && !worker.join_within(CLOSE_LIMIT)
        {
            log::warn(&format_args!(
                "{}: the Zenoh session did not close within {CLOSE_LIMIT:?}; it is left to close on its own",
                self.label
            ));
        }
    }
}

/// The session's thread, and the channel that says when it has ended.
struct Worker {
    thread: JoinHandle<()>,
    /// Disconnected when the thread ends (its sender goes with the thread's closure).
    ended: Receiver<()>,
}

impl Worker {
    /// Runs `session` on a thread named `zenoh`.
    fn spawn(session: impl FnOnce() + Send + 'static) -> io::Result<Worker> {
        let (ends, ended) = mpsc::channel::<()>();
        let thread = std::thread::Builder::new()
            .name("zenoh".into())
            .spawn(move || {
                let _ends = ends;
                session();
            })?;
        Ok(Worker { thread, ended })
    }

    /// Waits at most `limit` for the thread to end and joins it; whether it ended. A
    /// thread still running is left to end on its own (a peer that does not answer
    /// cannot hold the loop, and with it every other link).
    fn join_within(self, limit: Duration) -> bool {
        match self.ended.recv_timeout(limit) {
            Err(RecvTimeoutError::Timeout) => false,
            Ok(()) | Err(RecvTimeoutError::Disconnected) => {
                let _ = self.thread.join();
                true
            }
        }
    }
}

impl Drop for ZenohDriver {
    fn drop(&mut self) {
        let (out, malformed) = (self.dropped_out, self.malformed);
        let dropped_in = self.shared.dropped_in.load(Ordering::Relaxed);
        let put_errors = self.shared.put_errors.load(Ordering::Relaxed);
        if out + malformed + dropped_in + put_errors > 0 {
            log::warn(&format_args!(
                "{}: {dropped_in} samples dropped (the loop was behind), {malformed} samples not one MAVLink frame, {out} frames dropped (the session was behind), {put_errors} publications failed",
                self.label
            ));
        }
        self.stop();
    }
}

impl Driver for ZenohDriver {
    fn interface(&self) -> InterfaceId {
        self.interface
    }

    fn fd(&self) -> Option<RawFd> {
        None
    }

    fn woken(&self) -> bool {
        true
    }

    fn open(&mut self, _engine: &mut Engine, _now: Timestamp) -> io::Result<bool> {
        self.stop();
        *self.shared.opened.lock().unwrap_or_else(|e| e.into_inner()) = None;
        let zconfig = session_config(&self.config).map_err(io::Error::other)?;
        let (to_loop, inbox) = mpsc::sync_channel(INBOX);
        let (outbox, commands) = mpsc::sync_channel(OUTBOX);
        let shared = self.shared.clone();
        let config = self.config.clone();
        let worker =
            Worker::spawn(move || run_session(zconfig, &config, &commands, &to_loop, &shared))?;
        self.worker = Some(worker);
        self.inbox = Some(inbox);
        self.outbox = Some(outbox);
        self.opening = true;
        // Open once the session's thread says so (it rings the waker).
        Ok(false)
    }

    fn close(&mut self) {
        self.stop();
    }

    fn receive(&mut self, engine: &mut Engine, now: Timestamp) -> Progress {
        self.shared.woken.store(false, Ordering::Release);
        if self.finish_open(engine, now).is_err() {
            return Progress::Lost;
        }
        let Some(inbox) = self.inbox.as_ref().filter(|_| !self.opening) else {
            return Progress::Done;
        };
        let mut progress = Progress::More;
        for _ in 0..SAMPLES_PER_TURN {
            match inbox.try_recv() {
                Ok(bytes) => {
                    if is_one_frame(&bytes) {
                        engine.handle_message(self.interface, &bytes, now);
                    } else {
                        self.malformed += 1;
                    }
                }
                Err(TryRecvError::Empty | TryRecvError::Disconnected) => {
                    progress = Progress::Done;
                    break;
                }
            }
        }
        self.refresh_subscriptions(engine, now);
        progress
    }

    fn flush(&mut self, engine: &mut Engine, now: Timestamp) -> Progress {
        if self.finish_open(engine, now).is_err() {
            return Progress::Lost;
        }
        if self.opening {
            return Progress::Done;
        }
        self.refresh_subscriptions(engine, now);
        let Some(outbox) = &self.outbox else {
            return Progress::Done;
        };
        let dialect = engine.config().dialect;
        loop {
            engine.poll_transmit(self.interface, now, SEND_BATCH, &mut self.in_flight);
            let handed_out = self.in_flight.len();
            while let Some(t) = self.in_flight.pop_front() {
                let key = key_of(&self.config.prefix, &t.packet, &dialect);
                match outbox.try_send(Command::Put(key, t.packet.to_vec())) {
                    Ok(()) => engine.on_sent(&t),
                    Err(TrySendError::Full(_) | TrySendError::Disconnected(_)) => {
                        self.dropped_out += 1;
                        let why = io::Error::other("the Zenoh session is behind");
                        engine.on_send_failed(self.interface, &t, &why);
                    }
                }
            }
            if handed_out < SEND_BATCH {
                return Progress::Done;
            }
        }
    }

    fn idle(&self) -> bool {
        self.in_flight.is_empty()
    }
}

/// True if `bytes` is exactly one frame by its header's length (the parser checks the
/// rest): a sample is never part of a frame, nor several.
fn is_one_frame(bytes: &[u8]) -> bool {
    HeaderRepr::parse(bytes).is_ok_and(|h| h.frame_len() == bytes.len())
}

/// The key of `frame` under `prefix`:
/// `{prefix}/{target system|all}/{source system}/{source component}/{MESSAGE}`.
pub(crate) fn key_of(prefix: &str, frame: &[u8], dialect: &Dialect) -> String {
    match Frame::parse_exact_in(frame, dialect) {
        Ok(f) => {
            let destination = match f.target() {
                Some(t) if t.system != 0 => t.system.to_string(),
                _ => "all".to_string(),
            };
            let (system, component) = (f.system(), f.component());
            if f.is_unknown() {
                let id = f.message_id();
                format!("{prefix}/{destination}/{system}/{component}/{id}")
            } else {
                let name = f.name();
                format!("{prefix}/{destination}/{system}/{component}/{name}")
            }
        }
        // Frames the core hands out passed its parser; one it could not view again
        // still goes out, to everyone.
        Err(_) => match HeaderRepr::parse(frame) {
            Ok(h) => format!("{prefix}/all/{}/{}/{}", h.system, h.component, h.message_id),
            Err(_) => format!("{prefix}/all/0/0/0"),
        },
    }
}

/// `text` without the source locations Zenoh's errors carry (` /path/to/file.rs:61.`,
/// sometimes after ` at`).
fn without_locations(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(at) = rest.find(" /") {
        let tail = &rest[at + 1..];
        let end = tail
            .find(|c: char| c.is_whitespace() || c == ']')
            .unwrap_or(tail.len());
        let kept = &rest[..at];
        if tail[..end].contains(".rs:") {
            out.push_str(kept.strip_suffix(" at").unwrap_or(kept).trim_end());
        } else {
            out.push_str(&rest[..at + 1 + end]);
        }
        rest = &tail[end..];
    }
    out.push_str(rest);
    out.trim_end().to_string()
}

/// How often an edge looks again at the systems reached elsewhere when nothing was
/// learned or lost (their addresses may have expired).
const RECHECK: Duration = Duration::from_secs(1);

/// How Zenoh retries an endpoint it cannot reach or lost (its default: after 1 s,
/// doubling up to every 4 s).
const RETRY: &str = r#"{ period_init_ms: 200, period_max_ms: 1000, period_increase_factor: 2 }"#;

/// The session's configuration: the block's mode and endpoints, no multicast scouting
/// (sessions find each other only through the endpoints written), and an open that
/// does not wait for the first connection. A client whose Zenoh router is not there
/// fails to open, and the driver retries the open; a peer opens at once and Zenoh
/// retries each `connect` endpoint in the background, forever (with a zero timeout it
/// would try a peer that is not listening yet once and never again).
fn session_config(z: &ZenohInterface) -> Result<zenoh::Config, String> {
    let mut c = zenoh::Config::default();
    let json = |v: &[String]| serde_json::to_string(v).unwrap_or_else(|_| "[]".into());
    let mode = match z.mode {
        ZenohMode::Client => "\"client\"",
        ZenohMode::Peer => "\"peer\"",
    };
    let connect_timeout = match z.mode {
        ZenohMode::Client => "0",
        ZenohMode::Peer => "-1",
    };
    let settings = [
        ("mode", mode.to_string()),
        ("connect/endpoints", json(&z.connect)),
        ("listen/endpoints", json(&z.listen)),
        ("scouting/multicast/enabled", "false".into()),
        ("connect/timeout_ms", connect_timeout.into()),
        ("connect/exit_on_failure", "false".into()),
        // Retried as a TCP client is: after 0.2 s, doubling up to every second.
        ("connect/retry", RETRY.into()),
    ];
    for (key, value) in settings {
        c.insert_json5(key, &value)
            .map_err(|e| format!("zenoh setting {key}: {e}"))?;
    }
    Ok(c)
}

/// The session's thread: opens the session, subscribes, then publishes what the loop
/// sends until the loop lets go of the channel.
fn run_session(
    config: zenoh::Config,
    z: &ZenohInterface,
    commands: &Receiver<Command>,
    to_loop: &SyncSender<Vec<u8>>,
    shared: &Arc<Shared>,
) {
    let opened = zenoh::open(config).wait();
    let outcome = opened
        .as_ref()
        .map(|_| ())
        .map_err(|e| without_locations(&e.to_string()));
    *shared.opened.lock().unwrap_or_else(|e| e.into_inner()) = Some(outcome);
    // The loop learns the outcome from the waker: `flush` (after a look-up-like wait)
    // or `receive` takes it.
    let _ = shared.waker.wake();
    let Ok(session) = opened else {
        return;
    };
    let deliver = {
        let to_loop = to_loop.clone();
        let shared = shared.clone();
        move |sample: Sample| {
            let bytes = sample.payload().to_bytes().into_owned();
            match to_loop.try_send(bytes) {
                Ok(()) => shared.ring(),
                Err(TrySendError::Full(_)) => {
                    shared.dropped_in.fetch_add(1, Ordering::Relaxed);
                }
                Err(TrySendError::Disconnected(_)) => {}
            }
        }
    };
    let subscribe = |key: String| -> Option<Subscriber<()>> {
        let declared = session
            .declare_subscriber(key.clone())
            .callback(deliver.clone())
            .allowed_origin(Locality::Remote)
            .wait();
        match declared {
            Ok(s) => Some(s),
            Err(e) => {
                log::error(&format_args!("zenoh: cannot subscribe to {key}: {e}"));
                None
            }
        }
    };
    let prefix = &z.prefix;
    let _everything = match z.receive {
        ZenohReceive::All => subscribe(format!("{prefix}/**")),
        ZenohReceive::Addressed => subscribe(format!("{prefix}/all/**")),
    };
    let mut per_system: HashMap<u8, Subscriber<()>> = HashMap::new();
    while let Ok(command) = commands.recv() {
        match command {
            Command::Put(key, bytes) => {
                let put = session
                    .put(key, bytes)
                    .allowed_destination(Locality::Remote)
                    .wait();
                if put.is_err() {
                    shared.put_errors.fetch_add(1, Ordering::Relaxed);
                }
            }
            Command::Subscribe(systems) => {
                per_system.retain(|s, _| systems.contains(*s));
                for system in systems.iter() {
                    if !per_system.contains_key(&system)
                        && let Some(s) = subscribe(format!("{prefix}/{system}/**"))
                    {
                        per_system.insert(system, s);
                    }
                }
            }
        }
    }
    drop(per_system);
    let _ = session.close().wait();
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::encode::{Header, encode_v2};

    fn frame(id: u32, payload: &[u8]) -> Vec<u8> {
        let header = Header {
            seq: 0,
            system: 7,
            component: 1,
        };
        let mut out = Vec::new();
        encode_v2(header, id, payload, None, &mut out).expect("encode");
        out
    }

    #[test]
    fn keys_name_destination_source_and_message() {
        let d = Dialect::builtin();
        let heartbeat = frame(0, &[0; 9]);
        assert_eq!(key_of("f/a", &heartbeat, &d), "f/a/all/7/1/HEARTBEAT");
        // COMMAND_LONG (76): target system at payload byte 30, component at 31.
        let mut payload = [0u8; 33];
        payload[30] = 3;
        payload[31] = 1;
        assert_eq!(
            key_of("f/a", &frame(76, &payload), &d),
            "f/a/3/7/1/COMMAND_LONG"
        );
        payload[30] = 0;
        assert_eq!(
            key_of("f/a", &frame(76, &payload), &d),
            "f/a/all/7/1/COMMAND_LONG"
        );
    }

    #[test]
    fn errors_lose_their_source_locations() {
        assert_eq!(
            without_locations(
                "Can not listen on tcp/1.2.3.4:5: [1.2.3.4:5: in use (os error 98) /x/tcp.rs:61.] /x/unicast.rs:338."
            ),
            "Can not listen on tcp/1.2.3.4:5: [1.2.3.4:5: in use (os error 98)]"
        );
        assert_eq!(
            without_locations("Unable to connect to any of [tcp/1.2.3.4:5]!  /x/y.rs:447."),
            "Unable to connect to any of [tcp/1.2.3.4:5]!"
        );
        assert_eq!(
            without_locations("no file /etc/x here at /a/b.rs:1."),
            "no file /etc/x here"
        );
    }

    #[test]
    fn a_session_thread_that_does_not_end_is_left_after_the_limit() {
        let (release, held) = mpsc::channel::<()>();
        let stuck = Worker::spawn(move || {
            let _ = held.recv();
        })
        .expect("thread");
        assert!(!stuck.join_within(Duration::from_millis(50)));
        release.send(()).expect("the thread is still there");
        let quick = Worker::spawn(|| {}).expect("thread");
        assert!(quick.join_within(Duration::from_secs(10)));
    }

    #[test]
    fn a_sample_must_be_exactly_one_frame() {
        let heartbeat = frame(0, &[0; 9]);
        assert!(is_one_frame(&heartbeat));
        assert!(!is_one_frame(&heartbeat[..heartbeat.len() - 1]));
        assert!(!is_one_frame(&[heartbeat.clone(), heartbeat].concat()));
        assert!(!is_one_frame(b"hello"));
    }
}
