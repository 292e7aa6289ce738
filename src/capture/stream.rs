//! Reading a capture from any [`Read`] as it comes: a file of any size in constant
//! memory, or standard input while it is being written. Units are handed over as soon
//! as their last byte has arrived.

use std::io::{self, Read};

use super::records::{MAX_RECORD, RecordFormat};
use super::window::Window;
use super::{CaptureError, Format, Unit, detect, pcap, pcapng, tlog};

/// Bytes [`detect`] looks at.
const DETECT_LEN: usize = tlog::TIMESTAMP_LEN + 1;
/// Room for the longest record kept whole and one read beyond it.
const CAPACITY: usize = MAX_RECORD + 64 * 1024;

/// What a capture is read into.
pub trait Units {
    /// Takes one unit, in input order; returning false stops the reading.
    fn unit(&mut self, unit: Unit<'_>) -> bool;

    /// Called before the input is asked for more bytes, which may wait for them to
    /// arrive: the moment to flush output, so that a live capture is shown as it comes.
    fn waiting(&mut self) {}
}

/// How the reading of a capture ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct End {
    /// Bytes in the input: all of it, also after an error (the rest is read and
    /// dropped); where it stopped, if the [`Units`] stopped it.
    pub bytes: u64,
    /// The problem that stopped the reading before the end, if any.
    pub error: Option<CaptureError>,
    /// The [`Units`] asked to stop.
    pub stopped: bool,
    /// Packets of a pcap or pcapng capture passed over: not IPv4/UDP, or of a link
    /// type this reader does not know.
    pub passed_over: u64,
}

/// A capture being read from `R`, its format told from its first bytes.
pub struct Capture<R> {
    window: Window<R>,
    format: Format,
}

impl<R: Read> Capture<R> {
    /// Reads the first bytes of `input` (waiting for as many as it takes to tell the
    /// format, or for the input to end) and tells the format.
    pub fn new(input: R) -> io::Result<Self> {
        let mut window = Window::new(input, CAPACITY);
        window.fill_to(DETECT_LEN, &mut || {})?;
        let format = detect(window.bytes());
        Ok(Capture { window, format })
    }

    /// The capture's format.
    pub fn format(&self) -> Format {
        self.format
    }

    /// Hands every unit of the capture to `units`, in order, until the input ends, a
    /// problem stops the reading, or `units` asks to stop. Errors are those of the input.
    pub fn read(mut self, units: &mut impl Units) -> io::Result<End> {
        let w = &mut self.window;
        let mut passed_over = 0;
        let outcome = match self.format {
            Format::Raw => raw(w, units),
            Format::Tlog => records(w, &mut tlog::Tlog, units),
            Format::Pcap => {
                let mut wait = || units.waiting();
                w.fill_to(pcap::GLOBAL_HEADER_LEN, &mut wait)?;
                match pcap::Pcap::from_header(w.bytes()) {
                    Ok(mut format) => {
                        w.consume(pcap::GLOBAL_HEADER_LEN, pcap::GLOBAL_HEADER_LEN as u64);
                        let outcome = records(w, &mut format, units);
                        passed_over = format.passed_over();
                        outcome
                    }
                    Err(e) => Ok(Outcome::Failed(e.into())),
                }
            }
            Format::PcapNg => {
                w.fill_to(pcapng::FILE_HEADER_LEN, &mut || units.waiting())?;
                match pcapng::PcapNg::from_header(w.bytes()) {
                    Ok(mut format) => {
                        let outcome = records(w, &mut format, units);
                        passed_over = format.passed_over();
                        outcome
                    }
                    Err(e) => Ok(Outcome::Failed(e.into())),
                }
            }
        }?;
        Ok(match outcome {
            Outcome::Done => End {
                bytes: w.offset(),
                error: None,
                stopped: false,
                passed_over,
            },
            Outcome::Stopped => End {
                bytes: w.offset(),
                error: None,
                stopped: true,
                passed_over,
            },
            Outcome::Failed(error) => End {
                bytes: w.drain(&mut || units.waiting())?,
                error: Some(error),
                stopped: false,
                passed_over,
            },
        })
    }
}

/// How a walk over the units ended.
enum Outcome {
    Done,
    Stopped,
    Failed(CaptureError),
}

/// A raw stream: every read is a unit, continuing the one before.
fn raw<R: Read>(w: &mut Window<R>, units: &mut impl Units) -> io::Result<Outcome> {
    loop {
        if w.bytes().is_empty() && w.read_more(&mut || units.waiting())? == 0 {
            return Ok(Outcome::Done);
        }
        let held = w.bytes().len();
        let unit = Unit {
            timestamp_us: None,
            offset: w.offset(),
            bytes: w.bytes(),
            source: None,
        };
        if !units.unit(unit) {
            return Ok(Outcome::Stopped);
        }
        w.consume(held, held as u64);
    }
}

/// A record-based capture: each record is read whole (up to [`MAX_RECORD`] bytes)
/// before what it carries is handed over.
fn records<R: Read, F: RecordFormat>(
    w: &mut Window<R>,
    format: &mut F,
    units: &mut impl Units,
) -> io::Result<Outcome>
where
    F::Error: Into<CaptureError>,
{
    loop {
        if w.bytes().is_empty() && w.read_more(&mut || units.waiting())? == 0 {
            return Ok(Outcome::Done);
        }
        let at = w.offset();
        let len = loop {
            let held = w.bytes();
            match format.record_len(&held[..held.len().min(F::HEAD)], at) {
                Ok(len) => break len,
                // Decided on fewer bytes than it may look at: wait for more, unless
                // the input has ended (then the answer stands).
                Err(_) if held.len() < F::HEAD && w.read_more(&mut || units.waiting())? > 0 => {}
                Err(e) => return Ok(Outcome::Failed(e.into())),
            }
        };
        let keep = usize::try_from(len).map_or(MAX_RECORD, |l| l.min(MAX_RECORD));
        let whole = w.fill_to(keep, &mut || units.waiting())?
            && (len == keep as u64
                || w.discard_after(keep, len - keep as u64, &mut || units.waiting())?);
        if !whole {
            return Ok(Outcome::Failed(format.truncated(at).into()));
        }
        match format.item(&w.bytes()[..keep], at, len) {
            Ok(Some(item)) => {
                if !units.unit(F::unit(item)) {
                    return Ok(Outcome::Stopped);
                }
            }
            Ok(None) => {}
            Err(e) => return Ok(Outcome::Failed(e.into())),
        }
        w.consume(keep, len);
    }
}
