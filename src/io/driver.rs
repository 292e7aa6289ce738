//! What every transport driver does for the event loop: move bytes between the operating
//! system and the routing core ([`Engine`]), and nothing else. A new transport is one
//! file implementing [`Driver`] and its config block; the loop does not change.

use std::io;
use std::os::fd::RawFd;

use crate::routing::{Engine, InterfaceId, Timestamp};

/// A [`Driver::deadline`] with nothing due: it keeps the driver looked at once a second,
/// for a driver whose deadlines come and go (a listener's retry, a client's attempt).
pub(super) const NOTHING_DUE: Timestamp = Timestamp::from_nanos(u64::MAX);

/// How a call into a driver ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Progress {
    /// Everything waiting was handled.
    Done,
    /// Its turn ended with input still waiting: call `receive` again soon.
    More,
    /// The operating system refused output: wait until the descriptor is writable.
    Blocked,
    /// The device is gone (already reported to the core): stop watching it, then
    /// [`Driver::close`] it.
    Lost,
}

/// A transport: a socket or a device, and the bytes in flight between it and the core.
pub trait Driver {
    /// The core's interface whose bytes this driver moves.
    fn interface(&self) -> InterfaceId;

    /// The descriptor to watch, while open.
    fn fd(&self) -> Option<RawFd>;

    /// Opens the device or connects when the core asks ([`crate::routing::Notice::Open`]):
    /// `Ok(true)` when it is open now, `Ok(false)` when it is still connecting (the driver
    /// then tells the core itself, from [`Driver::flush`], once it knows). Sockets that
    /// are open from the start need not override it.
    fn open(&mut self, _engine: &mut Engine, _now: Timestamp) -> io::Result<bool> {
        Ok(true)
    }

    /// A driver for a connection this one accepted (a TCP server), to be added to the
    /// loop; called after every [`Driver::receive`] until it gives `None`.
    fn take_accepted(&mut self) -> Option<Box<dyn Driver>> {
        None
    }

    /// True if its input arrives from threads of its own (not a descriptor), which ring
    /// the loop's waker: it is then read whenever the waker rings.
    fn woken(&self) -> bool {
        false
    }

    /// True if [`Driver::receive`] may end with input still waiting and [`Progress::Done`]
    /// (a datagram socket reads one datagram per wake-up while traffic is light, as
    /// `recvmsg` costs less than a batch call that then finds nothing more). The loop
    /// then watches its descriptor level-triggered, so what is left wakes it again.
    fn level_triggered(&self) -> bool {
        false
    }

    /// Closes the device after [`Progress::Lost`]; what was in flight is dropped.
    fn close(&mut self) {}

    /// Begins a clean end (at shutdown once what the core handed out is written, when a
    /// reload's removed interface closes, or after [`Driver::parting`]): shuts the
    /// sending side once what is still to go is out, so the peer gets all that was sent
    /// and then the end. True if the loop must then
    /// call [`Driver::linger`] until it says done before closing: Linux answers input
    /// that arrives after a TCP socket is closed with a reset, and discards what the
    /// peer has not acknowledged yet. Drivers without a stream need not override it.
    fn shut_write(&mut self) -> bool {
        false
    }

    /// After it reported [`Progress::Lost`]: true if it still has last words for the
    /// peer (why the connection ends: an HTTP error's answer, a WebSocket Close frame).
    /// The loop then ends it as at shutdown, through [`Driver::shut_write`] and
    /// [`Driver::linger`], rather than closing it at once: closed with the peer's bytes
    /// unread, the socket would be reset, and the reset may discard those words.
    fn parting(&self) -> bool {
        false
    }

    /// After [`Driver::shut_write`]: sends what is still to go, reads and drops what the
    /// peer still sends; true once closing loses nothing here (as a rule: the peer's
    /// system acknowledged everything, the peer ended, or the connection failed; a
    /// driver may wait for the peer's end, when the peer may still be sending).
    fn linger(&mut self) -> bool {
        true
    }

    /// Reads what is waiting (a bounded amount per turn) and hands it to the core.
    fn receive(&mut self, engine: &mut Engine, now: Timestamp) -> Progress;

    /// Sends what the core has for this interface, as far as the operating system
    /// takes it now.
    fn flush(&mut self, engine: &mut Engine, now: Timestamp) -> Progress;

    /// Sends the packet the core holds for a direct send on this interface
    /// ([`Engine::take_direct`]) at once, if nothing else of this driver is waiting to
    /// be written: `None` if it cannot (the loop then has the core queue it), else how
    /// the send went, as [`Driver::flush`] says it. Called right after an input that
    /// left such a packet ([`Engine::direct_interface`]); drivers that do not send one
    /// packet at a time need not override it.
    fn send_now(&mut self, _engine: &mut Engine, _now: Timestamp) -> Option<Progress> {
        None
    }

    /// True if nothing the core handed out is still waiting to be written.
    fn idle(&self) -> bool;

    /// The local port its UDP socket holds (or binds when it opens), if it has a fixed
    /// one: a driver a reload retired gives it up to a new socket that needs it.
    fn udp_port(&self) -> Option<u16> {
        None
    }

    /// When the driver wants [`Driver::expire`] called (a WebSocket handshake's time
    /// limit, a listener's next try after the system refused it a connection), if ever.
    /// Asked when the driver joins the loop, and then each second while it has one;
    /// the loop looks once a second, so the call comes up to a second late.
    fn deadline(&self) -> Option<Timestamp> {
        None
    }

    /// Its [`Driver::deadline`] has passed: [`Progress::Lost`] if it gave up (reported
    /// to the core), [`Progress::More`] if it wants [`Driver::receive`] called again.
    fn expire(&mut self, _engine: &mut Engine, _now: Timestamp) -> Progress {
        Progress::Done
    }
}
