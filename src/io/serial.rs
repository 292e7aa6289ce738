//! The driver of one `serial { }` interface: the port (raw 8N1, any baud rate, optional
//! RTS/CTS) as a non-blocking file. When to reopen a missing device is the core's.

use std::collections::VecDeque;
use std::fs::File;
use std::io::{self, Read, Write};
use std::os::fd::{AsRawFd, RawFd};

use super::driver::{Driver, Progress};
use super::sys;
use crate::config::SerialInterface;
use crate::routing::{Engine, InterfaceId, Timestamp, Transmit};

/// Bytes read per system call.
const READ_CHUNK: usize = 4096;
/// Reads per wake-up before the loop gets a turn to send.
const READS_PER_TURN: usize = 16;

fn open_port(config: &SerialInterface) -> io::Result<File> {
    let flow = if config.flow_control {
        serialport::FlowControl::Hardware
    } else {
        serialport::FlowControl::None
    };
    let port = serialport::new(&config.device, config.baudrate)
        .data_bits(serialport::DataBits::Eight)
        .parity(serialport::Parity::None)
        .stop_bits(serialport::StopBits::One)
        .flow_control(flow)
        .open_native()
        .map_err(io::Error::other)?;
    // Best effort: most USB-serial adapters and UARTs take it, a pty or a USB CDC device
    // may not, and the port works either way.
    let _ = sys::request_low_latency(&port);
    sys::nonblocking_file(port)
}

/// A serial port.
pub struct SerialDriver {
    interface: InterfaceId,
    config: SerialInterface,
    file: Option<File>,
    buffer: Vec<u8>,
    /// A packet partly written: the rest goes first when the port takes bytes again.
    partial: Option<(Transmit, usize)>,
    /// Scratch for [`Engine::poll_transmit`].
    next: VecDeque<Transmit>,
}

impl SerialDriver {
    /// A closed port for `config` and the core's interface `interface`.
    pub fn new(config: &SerialInterface, interface: InterfaceId) -> Self {
        SerialDriver {
            interface,
            config: config.clone(),
            file: None,
            buffer: vec![0; READ_CHUNK],
            partial: None,
            next: VecDeque::with_capacity(1),
        }
    }
}

impl Driver for SerialDriver {
    fn interface(&self) -> InterfaceId {
        self.interface
    }

    fn fd(&self) -> Option<RawFd> {
        self.file.as_ref().map(AsRawFd::as_raw_fd)
    }

    fn open(&mut self) -> io::Result<()> {
        self.file = Some(open_port(&self.config)?);
        Ok(())
    }

    fn close(&mut self) {
        self.file = None;
        self.partial = None;
    }

    fn receive(&mut self, engine: &mut Engine, now: Timestamp) -> Progress {
        for _ in 0..READS_PER_TURN {
            let Some(file) = &mut self.file else {
                return Progress::Done;
            };
            match file.read(&mut self.buffer) {
                Ok(0) => {
                    engine.stream_lost(self.interface, now, &"end of file");
                    return Progress::Lost;
                }
                Ok(n) => engine.handle_stream(self.interface, &self.buffer[..n], now),
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => return Progress::Done,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => {
                    engine.stream_lost(self.interface, now, &e);
                    return Progress::Lost;
                }
            }
        }
        Progress::More
    }

    fn flush(&mut self, engine: &mut Engine, now: Timestamp) -> Progress {
        loop {
            let Some(file) = &mut self.file else {
                return Progress::Done;
            };
            let (t, done) = match self.partial.take() {
                Some(p) => p,
                None => {
                    engine.poll_transmit(self.interface, now, 1, &mut self.next);
                    match self.next.pop_front() {
                        Some(t) => (t, 0),
                        None => return Progress::Done,
                    }
                }
            };
            match file.write(&t.packet[done..]) {
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
                    // The packet being written is lost with the device.
                    engine.on_send_failed(self.interface, &t, &e);
                    engine.stream_lost(self.interface, now, &e);
                    return Progress::Lost;
                }
            }
        }
    }

    fn idle(&self) -> bool {
        self.partial.is_none() || self.file.is_none()
    }
}
