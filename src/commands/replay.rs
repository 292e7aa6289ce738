//! `mavtables replay`: send a capture's frames to a UDP address or a serial port at
//! their recorded timing (scaled by a speed factor), or as fast as possible.

use std::io::{self, Write};
use std::net::{SocketAddr, ToSocketAddrs, UdpSocket};
use std::time::{Duration, Instant};

use crate::capture::{self, CaptureError};
use crate::wire::Parser;

/// Where to send.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Target {
    /// A UDP address (`udp:HOST:PORT`).
    Udp(SocketAddr),
    /// A serial device at a baud rate (`serial:DEVICE:BAUD`).
    Serial {
        /// Device path.
        device: String,
        /// Baud rate.
        baud: u32,
    },
}

impl Target {
    /// Parses `udp:HOST:PORT` or `serial:DEVICE:BAUD` (the device may contain `:`).
    pub fn parse(text: &str) -> Result<Self, String> {
        if let Some(rest) = text.strip_prefix("udp:") {
            let addr = rest
                .to_socket_addrs()
                .map_err(|e| format!("cannot resolve '{rest}': {e}"))?
                .next()
                .ok_or_else(|| format!("'{rest}' resolves to no address"))?;
            return Ok(Target::Udp(addr));
        }
        if let Some(rest) = text.strip_prefix("serial:") {
            let (device, baud) = rest
                .rsplit_once(':')
                .ok_or_else(|| format!("expected serial:DEVICE:BAUD, got '{text}'"))?;
            let baud = baud
                .parse::<u32>()
                .ok()
                .filter(|b| *b > 0)
                .ok_or_else(|| format!("invalid baud rate '{baud}'"))?;
            if device.is_empty() {
                return Err(format!("expected serial:DEVICE:BAUD, got '{text}'"));
            }
            return Ok(Target::Serial {
                device: device.to_string(),
                baud,
            });
        }
        Err(format!(
            "expected udp:HOST:PORT or serial:DEVICE:BAUD, got '{text}'"
        ))
    }
}

impl std::fmt::Display for Target {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Target::Udp(a) => write!(f, "udp:{a}"),
            Target::Serial { device, baud } => write!(f, "serial:{device}:{baud}"),
        }
    }
}

/// How fast to replay.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Speed {
    /// No waiting between frames.
    Max,
    /// Recorded timing divided by this factor (2.0 = twice as fast).
    Factor(f64),
}

impl Speed {
    /// Parses `max` or a positive number.
    pub fn parse(text: &str) -> Result<Self, String> {
        if text == "max" {
            return Ok(Speed::Max);
        }
        match text.parse::<f64>() {
            Ok(f) if f.is_finite() && f > 0.0 => Ok(Speed::Factor(f)),
            _ => Err(format!(
                "invalid speed '{text}' (a positive number, or 'max')"
            )),
        }
    }
}

/// One frame to send and when it was recorded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Timed<'a> {
    /// Capture time in µs since the UNIX epoch (`None` for raw streams).
    pub timestamp_us: Option<u64>,
    /// The frame's bytes.
    pub bytes: &'a [u8],
}

/// Every valid frame of a capture, in order. Invalid bytes are left out.
pub fn frames(data: &[u8]) -> Result<Vec<Timed<'_>>, CaptureError> {
    let mut out = Vec::new();
    let format = capture::detect(data);
    capture::for_each_unit(format, data, |unit| {
        let mut parser = Parser::new();
        let mut spans = Vec::new();
        parser.feed(unit.bytes, |f| {
            spans.push((f.offset() as usize, f.as_bytes().len()))
        });
        parser.finish_frames(|f| spans.push((f.offset() as usize, f.as_bytes().len())));
        for (o, l) in spans {
            out.push(Timed {
                timestamp_us: unit.timestamp_us,
                bytes: &unit.bytes[o..o + l],
            });
        }
        true
    })?;
    Ok(out)
}

/// Something frames can be written to.
trait Sender {
    fn send(&mut self, frame: &[u8]) -> io::Result<()>;
}

struct UdpSender {
    socket: UdpSocket,
    to: SocketAddr,
}

impl Sender for UdpSender {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        // A full socket buffer is a pause, not a failure: retry for up to a second.
        let deadline = Instant::now() + Duration::from_secs(1);
        loop {
            match self.socket.send_to(frame, self.to) {
                Ok(_) => return Ok(()),
                Err(e)
                    if matches!(e.kind(), io::ErrorKind::WouldBlock | io::ErrorKind::OutOfMemory)
                        || e.raw_os_error() == Some(105) /* ENOBUFS */ =>
                {
                    if Instant::now() > deadline {
                        return Err(e);
                    }
                    std::thread::sleep(Duration::from_micros(200));
                }
                Err(e) => return Err(e),
            }
        }
    }
}

struct SerialSender {
    port: serialport::TTYPort,
}

impl Sender for SerialSender {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        self.port.write_all(frame)
    }
}

fn open(target: &Target) -> io::Result<Box<dyn Sender>> {
    match target {
        Target::Udp(to) => {
            let bind: SocketAddr = if to.is_ipv4() {
                ([0, 0, 0, 0], 0).into()
            } else {
                ([0u16; 8], 0).into()
            };
            Ok(Box::new(UdpSender {
                socket: UdpSocket::bind(bind)?,
                to: *to,
            }))
        }
        Target::Serial { device, baud } => {
            let port = serialport::new(device, *baud)
                .timeout(Duration::from_secs(5))
                .open_native()
                .map_err(|e| io::Error::other(format!("cannot open {device}: {e}")))?;
            Ok(Box::new(SerialSender { port }))
        }
    }
}

/// What a replay did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Summary {
    /// Frames sent.
    pub frames: u64,
    /// Bytes sent.
    pub bytes: u64,
    /// Wall-clock time taken.
    pub elapsed: Duration,
}

/// Sends `frames` to `target` at `speed`, calling `progress(sent, total)` after each frame.
pub fn replay(
    frames: &[Timed<'_>],
    target: &Target,
    speed: Speed,
    progress: &mut dyn FnMut(usize, usize),
) -> io::Result<Summary> {
    let mut sender = open(target)?;
    let start = Instant::now();
    let first = frames.iter().find_map(|f| f.timestamp_us);
    let mut bytes = 0u64;
    for (i, f) in frames.iter().enumerate() {
        if let (Speed::Factor(k), Some(t0), Some(t)) = (speed, first, f.timestamp_us) {
            let due = start + Duration::from_secs_f64(t.saturating_sub(t0) as f64 / 1e6 / k);
            let now = Instant::now();
            if due > now {
                std::thread::sleep(due - now);
            }
        }
        sender.send(f.bytes)?;
        bytes += f.bytes.len() as u64;
        progress(i + 1, frames.len());
    }
    Ok(Summary {
        frames: frames.len() as u64,
        bytes,
        elapsed: start.elapsed(),
    })
}

/// Draws a one-line progress bar (for a terminal), at most ten times a second.
pub struct ProgressBar<W: Write> {
    out: W,
    start: Instant,
    last: Option<Instant>,
}

impl<W: Write> ProgressBar<W> {
    /// A bar drawn on `out`.
    pub fn new(out: W) -> Self {
        ProgressBar {
            out,
            start: Instant::now(),
            last: None,
        }
    }

    /// Redraws the bar for `done` of `total` (always on the last one).
    pub fn update(&mut self, done: usize, total: usize) {
        let now = Instant::now();
        if done < total
            && self
                .last
                .is_some_and(|l| now - l < Duration::from_millis(100))
        {
            return;
        }
        self.last = Some(now);
        const WIDTH: usize = 30;
        let filled = (done * WIDTH).checked_div(total).unwrap_or(WIDTH);
        let _ = write!(
            self.out,
            "\r[{}{}] {done}/{total} frames  {:.1} s",
            "#".repeat(filled),
            ".".repeat(WIDTH - filled),
            self.start.elapsed().as_secs_f64()
        );
        if done == total {
            let _ = writeln!(self.out);
        }
        let _ = self.out.flush();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn targets_and_speeds_parse() {
        assert_eq!(
            Target::parse("udp:127.0.0.1:14550"),
            Ok(Target::Udp(([127, 0, 0, 1], 14550).into()))
        );
        assert_eq!(
            Target::parse("serial:/dev/serial/by-id/usb-3D:Robotics-if00:921600"),
            Ok(Target::Serial {
                device: "/dev/serial/by-id/usb-3D:Robotics-if00".into(),
                baud: 921_600
            })
        );
        assert!(Target::parse("serial:/dev/ttyUSB0").is_err());
        assert!(Target::parse("serial:/dev/ttyUSB0:0").is_err());
        assert!(Target::parse("tcp:1.2.3.4:5").is_err());
        assert_eq!(Speed::parse("max"), Ok(Speed::Max));
        assert_eq!(Speed::parse("2.5"), Ok(Speed::Factor(2.5)));
        assert!(
            Speed::parse("0").is_err()
                && Speed::parse("-1").is_err()
                && Speed::parse("nan").is_err()
        );
    }

    #[test]
    fn progress_bar_draws_the_last_update() {
        let mut buf = Vec::new();
        let mut bar = ProgressBar::new(&mut buf);
        bar.update(1, 2);
        bar.update(2, 2);
        let text = String::from_utf8(buf).expect("utf-8");
        assert!(text.contains("] 2/2 frames"), "{text}");
        assert!(text.ends_with('\n'));
    }
}
