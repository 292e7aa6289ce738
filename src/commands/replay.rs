//! `mavtables replay`: send a capture's frames to a UDP address or a serial port at
//! their recorded timing (scaled by a speed factor), or as fast as possible.
//!
//! The capture is read as it is sent, from any [`Read`]: a file of any size in constant
//! memory, or standard input as it arrives.

use std::io::{self, Read, Write};
use std::net::{SocketAddr, ToSocketAddrs, UdpSocket};
use std::time::{Duration, Instant};

use crate::capture::{Capture, CaptureError, Format, Unit, Units};
use crate::dialect::Dialect;
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
            let found: Vec<SocketAddr> = rest
                .to_socket_addrs()
                .map_err(|e| format!("cannot resolve '{rest}': {e}"))?
                .collect();
            // An IPv4 address first when the name has both (`localhost` gives ::1 first
            // on many systems): routers and ground stations listen on IPv4 by default.
            let addr = (found.iter().find(|a| a.is_ipv4()))
                .or(found.first())
                .copied()
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

/// The longest a replay waits for a frame, however far apart its capture's timestamps
/// are or however slow `--speed` makes it (about 100 years: forever, in practice).
const LONGEST_WAIT: Duration = Duration::from_secs(100 * 365 * 86_400);

/// How long after the first frame a frame recorded `gap_us` µs after it is sent at
/// speed `factor`: never more than [`LONGEST_WAIT`], whatever a capture's timestamps say
/// (so the send time can always be counted).
fn wait_for(gap_us: u64, factor: f64) -> Duration {
    Duration::try_from_secs_f64(gap_us as f64 / 1e6 / factor)
        .map_or(LONGEST_WAIT, |wait| wait.min(LONGEST_WAIT))
}

/// One frame to send and when it was recorded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Timed<'a> {
    /// Capture time in µs since the UNIX epoch (`None` for raw streams).
    pub timestamp_us: Option<u64>,
    /// The frame's bytes.
    pub bytes: &'a [u8],
}

/// Why a replay (or a walk over a capture's frames) stopped short.
#[derive(Debug)]
pub enum ReplayError {
    /// Reading the capture failed.
    Input(io::Error),
    /// The capture is broken here; the frames before were handled.
    Capture(CaptureError),
    /// Sending failed (or opening the target did).
    Send(io::Error),
}

/// Hands the valid frames of each unit to `each`: one parser for a raw capture's
/// pieces, a fresh one for each tlog record or datagram.
struct FrameUnits<F> {
    each: F,
    stream: Option<Parser>,
    error: Option<io::Error>,
    /// The messages frames are checked against.
    dialect: Dialect,
}

impl<F: FnMut(Timed<'_>) -> io::Result<()>> FrameUnits<F> {
    fn frames(&mut self, parser: &mut Parser, timestamp_us: Option<u64>, bytes: &[u8], end: bool) {
        let (each, error) = (&mut self.each, &mut self.error);
        let mut send = |f: crate::wire::Frame<'_>| {
            if error.is_none()
                && let Err(e) = each(Timed {
                    timestamp_us,
                    bytes: f.as_bytes(),
                })
            {
                *error = Some(e);
            }
        };
        parser.feed(bytes, &mut send);
        if end {
            parser.finish_frames(send);
        }
    }
}

impl<F: FnMut(Timed<'_>) -> io::Result<()>> Units for FrameUnits<F> {
    fn unit(&mut self, unit: Unit<'_>) -> bool {
        match self.stream.take() {
            Some(mut parser) => {
                self.frames(&mut parser, None, unit.bytes, false);
                self.stream = Some(parser);
            }
            None => {
                let mut parser = Parser::new().with_dialect(self.dialect);
                self.frames(&mut parser, unit.timestamp_us, unit.bytes, true);
            }
        }
        self.error.is_none()
    }
}

/// Calls `each` with every valid frame of the capture read from `input`, in order, as
/// the capture is read (invalid bytes are left out; messages `dialect` does not know are
/// invalid). Stops at the first error `each` returns, which comes back as
/// [`ReplayError::Send`].
pub fn for_each_frame(
    input: impl Read,
    dialect: Dialect,
    each: impl FnMut(Timed<'_>) -> io::Result<()>,
) -> Result<(), ReplayError> {
    let capture = Capture::new(input).map_err(ReplayError::Input)?;
    let mut units = FrameUnits {
        each,
        stream: (capture.format() == Format::Raw).then(|| Parser::new().with_dialect(dialect)),
        error: None,
        dialect,
    };
    let end = capture.read(&mut units).map_err(ReplayError::Input)?;
    if let Some(mut parser) = units.stream.take() {
        units.frames(&mut parser, None, &[], true);
    }
    if let Some(e) = units.error {
        return Err(ReplayError::Send(e));
    }
    match end.error {
        Some(e) => Err(ReplayError::Capture(e)),
        None => Ok(()),
    }
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

/// Sends the frames of the capture read from `input` that `dialect` knows to `target`
/// at `speed`, as they are read, calling `progress(sent)` after each frame. Returns what was sent, and
/// what stopped the replay short, if anything.
pub(crate) fn replay(
    input: impl Read,
    target: &Target,
    speed: Speed,
    dialect: Dialect,
    progress: &mut dyn FnMut(u64),
) -> (Summary, Option<ReplayError>) {
    let start = Instant::now();
    let (mut frames, mut bytes) = (0u64, 0u64);
    let result = open(target)
        .map_err(ReplayError::Send)
        .and_then(|mut sender| {
            let mut first = None;
            for_each_frame(input, dialect, |f| {
                if let (Speed::Factor(k), Some(t)) = (speed, f.timestamp_us) {
                    let t0 = *first.get_or_insert(t);
                    let due = start + wait_for(t.saturating_sub(t0), k);
                    let now = Instant::now();
                    if due > now {
                        std::thread::sleep(due - now);
                    }
                }
                sender.send(f.bytes)?;
                frames += 1;
                bytes += f.bytes.len() as u64;
                progress(frames);
                Ok(())
            })
        });
    let summary = Summary {
        frames,
        bytes,
        elapsed: start.elapsed(),
    };
    (summary, result.err())
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
    pub(crate) fn update(&mut self, done: u64, total: u64) {
        if done < total && self.too_soon() {
            return;
        }
        const WIDTH: u64 = 30;
        let filled = (done.min(total) * WIDTH)
            .checked_div(total)
            .unwrap_or(WIDTH) as usize;
        let _ = write!(
            self.out,
            "\r[{}{}] {done}/{total} frames  {:.1} s",
            "#".repeat(filled),
            ".".repeat(WIDTH as usize - filled),
            self.start.elapsed().as_secs_f64()
        );
        if done == total {
            let _ = writeln!(self.out);
        }
        let _ = self.out.flush();
    }

    /// Redraws the count of `done` frames of a capture whose length is not known (one
    /// read from standard input).
    pub(crate) fn update_count(&mut self, done: u64) {
        if self.too_soon() {
            return;
        }
        let _ = write!(
            self.out,
            "\r{done} frames  {:.1} s",
            self.start.elapsed().as_secs_f64()
        );
        let _ = self.out.flush();
    }

    /// Ends the line of a count drawn with [`ProgressBar::update_count`].
    pub(crate) fn finish_count(&mut self, done: u64) {
        self.last = None;
        self.update_count(done);
        let _ = writeln!(self.out);
    }

    /// True if the last redraw was less than 0.1 s ago; otherwise notes this one.
    fn too_soon(&mut self) -> bool {
        let now = Instant::now();
        if self
            .last
            .is_some_and(|l| now - l < Duration::from_millis(100))
        {
            return true;
        }
        self.last = Some(now);
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_waits_its_gap_over_the_speed_and_never_more_than_the_longest_wait() {
        assert_eq!(wait_for(2_000_000, 2.0), Duration::from_secs(1));
        assert_eq!(wait_for(0, 1e-300), Duration::ZERO);
        // Speeds and gaps no clock can count wait the longest, without a panic.
        for (gap, speed) in [
            (1, 1e-300),
            (u64::MAX, 1.0),
            (u64::MAX, 1e-10),
            (1_000, f64::MIN_POSITIVE),
        ] {
            assert_eq!(wait_for(gap, speed), LONGEST_WAIT, "{gap} {speed}");
            let _due = Instant::now() + wait_for(gap, speed);
        }
    }

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
