//! Moving bytes of a byte stream (a serial port, a TCP connection) between a
//! non-blocking reader/writer and the core: bounded reads per turn, and writes that keep
//! a partly written frame to finish first, so a frame is never cut and never dropped
//! halfway while the stream lives.
//!
//! A failed write does not end the stream at once: what the peer sent before it went
//! away may still wait to be read (a peer that sends its last frame and closes makes the
//! next write fail, often before the loop has read that frame). The loss is reported by
//! the next [`StreamIo::receive`] once it has read everything, or by the next
//! [`StreamIo::flush`] if no read came in between.

use std::collections::VecDeque;
use std::fmt::Display;
use std::io::{self, Read, Write};

use super::driver::Progress;
use crate::routing::{Engine, InterfaceId, Timestamp, Transmit};

/// Bytes read per system call.
const READ_CHUNK: usize = 4096;
/// Reads per wake-up before the loop gets a turn to send.
const READS_PER_TURN: usize = 16;

/// The bytes in flight of one stream.
pub struct StreamIo {
    buffer: Vec<u8>,
    /// A packet partly written: the rest goes first when the stream takes bytes again.
    partial: Option<(Transmit, usize)>,
    /// Scratch for [`Engine::poll_transmit`].
    next: VecDeque<Transmit>,
    /// A write failed: the stream is lost once what is left to read has been read.
    failed: Option<io::Error>,
}

impl Default for StreamIo {
    fn default() -> Self {
        StreamIo {
            buffer: vec![0; READ_CHUNK],
            partial: None,
            next: VecDeque::with_capacity(1),
            failed: None,
        }
    }
}

impl StreamIo {
    /// Forgets what was in flight (the stream is gone).
    pub fn clear(&mut self) {
        self.partial = None;
        self.failed = None;
    }

    /// True if no frame is partly written.
    pub fn idle(&self) -> bool {
        self.partial.is_none()
    }

    /// Reads what `stream` has (a bounded amount) into the core's interface `id`. End of
    /// stream and errors are reported to the core as a loss, and so is a failed write
    /// once nothing is left to read.
    pub fn receive(
        &mut self,
        stream: &mut impl Read,
        engine: &mut Engine,
        id: InterfaceId,
        now: Timestamp,
    ) -> Progress {
        for _ in 0..READS_PER_TURN {
            match stream.read(&mut self.buffer) {
                Ok(0) => {
                    return match self.failed.take() {
                        Some(e) => self.lose(engine, id, now, &e, true),
                        None => self.lose(engine, id, now, &"end of stream", false),
                    };
                }
                Ok(n) => engine.handle_stream(id, &self.buffer[..n], now),
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => {
                    return match self.failed.take() {
                        Some(e) => self.lose(engine, id, now, &e, true),
                        None => Progress::Done,
                    };
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => {
                    let why = self.failed.take().unwrap_or(e);
                    return self.lose(engine, id, now, &why, true);
                }
            }
        }
        Progress::More
    }

    /// Reports the stream's loss to the core (`error`: for a failed read or write, not
    /// a plain end), after counting the frame it cut (partly written) as dropped: that
    /// is counted while its link is still there, since the loss of an accepted
    /// connection removes the link.
    fn lose(
        &mut self,
        engine: &mut Engine,
        id: InterfaceId,
        now: Timestamp,
        why: &dyn Display,
        error: bool,
    ) -> Progress {
        if let Some((t, _)) = self.partial.take() {
            engine.on_stream_frame_lost(&t);
        }
        if error {
            engine.stream_broken(id, now, why);
        } else {
            engine.stream_lost(id, now, why);
        }
        Progress::Lost
    }

    /// Writes what the core has for interface `id`, highest priority first, as far as
    /// `stream` takes it. A write error drops the frame being written and stops the
    /// writing; it gives `Blocked`, so that the loop watches the descriptor, whose error
    /// wakes it to read what is left ([`StreamIo::receive`] then reports the loss). If
    /// the loop flushes again without a read in between, the loss is reported here.
    pub fn flush(
        &mut self,
        stream: &mut impl Write,
        engine: &mut Engine,
        id: InterfaceId,
        now: Timestamp,
    ) -> Progress {
        if let Some(e) = self.failed.take() {
            return self.lose(engine, id, now, &e, true);
        }
        loop {
            let (t, done) = match self.partial.take() {
                Some(p) => p,
                None => {
                    engine.poll_transmit(id, now, 1, &mut self.next);
                    match self.next.pop_front() {
                        Some(t) => (t, 0),
                        None => return Progress::Done,
                    }
                }
            };
            match stream.write(&t.packet[done..]) {
                Ok(n) if done + n == t.packet.len() => engine.on_sent(&t),
                Ok(0) => {
                    self.partial = Some((t, done));
                    return Progress::Blocked;
                }
                Ok(n) => self.partial = Some((t, done + n)),
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => {
                    self.partial = Some((t, done));
                    return Progress::Blocked;
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => self.partial = Some((t, done)),
                Err(e) => {
                    engine.on_stream_frame_lost(&t);
                    self.failed = Some(e);
                    return Progress::Blocked;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use std::net::SocketAddr;

    use super::*;
    use crate::config::load;
    use crate::routing::RouterOptions;
    use crate::wire::encode::{Header, encode_v2};

    const T0: Timestamp = Timestamp::ZERO;

    /// A peer that takes `room` bytes, then answers every write with `then`.
    struct Peer {
        room: usize,
        then: io::ErrorKind,
    }

    impl Write for Peer {
        fn write(&mut self, bytes: &[u8]) -> io::Result<usize> {
            match self.room.min(bytes.len()) {
                0 => Err(self.then.into()),
                n => {
                    self.room -= n;
                    Ok(n)
                }
            }
        }

        fn flush(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    /// A peer that has closed: nothing is left to read.
    struct Ended;

    impl Read for Ended {
        fn read(&mut self, _: &mut [u8]) -> io::Result<usize> {
            Ok(0)
        }
    }

    /// A core with a UDP interface and a TCP client, opened, with two broadcasts from
    /// the UDP side queued for the client.
    fn queued_for_client() -> (Engine, InterfaceId) {
        let config = load("chain default { accept; }\n").expect("config").config;
        let mut e = Engine::new(&config, RouterOptions::default());
        let udp = e.add_datagram_interface("udp test".into(), 0, Default::default());
        let client = e.add_stream_client("tcp connect x".into(), "tcp:x", 0, T0);
        e.handle_timeout(T0);
        e.stream_opened(client, T0);
        for seq in 0..2 {
            e.handle_datagram(udp, FROM, &attitude(seq), T0);
        }
        (e, client)
    }

    /// Where the UDP side's frames come from.
    const FROM: SocketAddr = SocketAddr::V4(std::net::SocketAddrV4::new(
        std::net::Ipv4Addr::LOCALHOST,
        1,
    ));

    /// An ATTITUDE broadcast from 7.1 with sequence number `seq`.
    fn attitude(seq: u8) -> Vec<u8> {
        let header = Header {
            seq,
            system: 7,
            component: 1,
        };
        let mut frame = Vec::new();
        encode_v2(header, 30, &[7; 28], None, &mut frame).expect("encode");
        frame
    }

    /// The report's line of `label`.
    fn line(e: &Engine, label: &str) -> String {
        let report = e.report();
        let found = report.lines().find(|l| l.trim_start().starts_with(label));
        found
            .unwrap_or_else(|| panic!("no {label} in {report}"))
            .to_string()
    }

    #[test]
    fn a_failed_write_is_one_io_error_and_one_dropped_frame() {
        let (mut e, client) = queued_for_client();
        let mut io = StreamIo::default();
        let mut peer = Peer {
            room: 0,
            then: io::ErrorKind::BrokenPipe,
        };
        assert_eq!(io.flush(&mut peer, &mut e, client, T0), Progress::Blocked);
        assert_eq!(io.receive(&mut Ended, &mut e, client, T0), Progress::Lost);
        assert!(
            line(&e, "tcp connect x").contains(" 1 I/O errors"),
            "{}",
            e.report()
        );
        assert!(
            line(&e, "tcp:x").contains("+ 1 (send errors)"),
            "{}",
            e.report()
        );
    }

    #[test]
    fn a_failed_write_on_an_accepted_connection_is_one_io_error_of_its_server() {
        let config = load("chain default { accept; }\n").expect("config").config;
        let mut e = Engine::new(&config, RouterOptions::default());
        let udp = e.add_datagram_interface("udp test".into(), 0, Default::default());
        let server = e.add_listener("tcp test".into(), Default::default(), 0);
        let peer = SocketAddr::from(([127, 0, 0, 1], 9));
        let conn = e.accept(server, peer, T0).expect("accepted");
        e.handle_datagram(udp, FROM, &attitude(0), T0);
        let mut io = StreamIo::default();
        let mut broken = Peer {
            room: 0,
            then: io::ErrorKind::ConnectionReset,
        };
        assert_eq!(io.flush(&mut broken, &mut e, conn, T0), Progress::Blocked);
        assert_eq!(io.receive(&mut Ended, &mut e, conn, T0), Progress::Lost);
        assert!(
            line(&e, "tcp test").contains(" 1 I/O errors"),
            "{}",
            e.report()
        );
    }

    #[test]
    fn a_frame_cut_by_the_streams_end_is_counted_as_dropped() {
        let (mut e, client) = queued_for_client();
        let mut io = StreamIo::default();
        let mut peer = Peer {
            room: 5,
            then: io::ErrorKind::WouldBlock,
        };
        assert_eq!(io.flush(&mut peer, &mut e, client, T0), Progress::Blocked);
        assert!(!io.idle());
        assert_eq!(io.receive(&mut Ended, &mut e, client, T0), Progress::Lost);
        assert!(io.idle());
        let link = line(&e, "tcp:x");
        assert!(
            link.contains("out 0 frames") && link.contains("+ 1 (send errors)"),
            "{link}"
        );
    }
}
