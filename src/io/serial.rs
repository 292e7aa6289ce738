//! The driver of one `serial { }` interface: the port (raw 8N1, any baud rate, optional
//! RTS/CTS) as a non-blocking file. When to reopen a missing device is the core's.

use std::fs::File;
use std::io;
use std::os::fd::{AsRawFd, RawFd};

use super::driver::{Driver, Progress};
use super::stream::StreamIo;
use super::sys;
use crate::config::SerialInterface;
use crate::routing::{Engine, InterfaceId, Timestamp};

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
pub(super) struct SerialDriver {
    interface: InterfaceId,
    config: SerialInterface,
    file: Option<File>,
    io: StreamIo,
}

impl SerialDriver {
    /// A closed port for `config` and the core's interface `interface`.
    pub(super) fn new(config: &SerialInterface, interface: InterfaceId) -> Self {
        SerialDriver {
            interface,
            config: config.clone(),
            file: None,
            io: StreamIo::default(),
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

    fn open(&mut self, _engine: &mut Engine, _now: Timestamp) -> io::Result<bool> {
        self.file = Some(open_port(&self.config)?);
        Ok(true)
    }

    fn close(&mut self) {
        self.file = None;
        self.io.clear();
    }

    fn receive(&mut self, engine: &mut Engine, now: Timestamp) -> Progress {
        match &mut self.file {
            Some(file) => self.io.receive(file, engine, self.interface, now),
            None => Progress::Done,
        }
    }

    fn flush(&mut self, engine: &mut Engine, now: Timestamp) -> Progress {
        match &mut self.file {
            Some(file) => self.io.flush(file, engine, self.interface, now),
            None => Progress::Done,
        }
    }

    fn idle(&self) -> bool {
        self.io.idle() || self.file.is_none()
    }
}
