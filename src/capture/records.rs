//! What a record-based capture format (tlog, pcap, pcapng) tells the readers: how long
//! the record at hand is, from its first bytes, and what a whole record carries. The
//! streaming [`super::Capture`] and the in-memory [`Records`] iterator both walk a
//! capture with these answers, so they agree on every byte.

use super::Unit;

/// The longest record kept whole. A longer one (only a packet capture's can be: a tlog
/// record is at most 8 + 280 bytes) is looked at through its first `MAX_RECORD` bytes
/// and the rest is skipped; as an IPv4 datagram is at most 64 KiB, no UDP payload is
/// lost.
pub const MAX_RECORD: usize = 256 * 1024;

/// One record-based capture format, and what it has learnt so far (byte order,
/// interfaces).
pub trait RecordFormat {
    /// What a record can carry.
    type Item<'a>;
    /// Why reading stopped.
    type Error;
    /// Most bytes [`RecordFormat::record_len`] looks at.
    const HEAD: usize;

    /// Length of the record at input offset `at` from its first bytes: `head` holds
    /// [`RecordFormat::HEAD`] bytes, fewer only where the input ends.
    fn record_len(&self, head: &[u8], at: u64) -> Result<u64, Self::Error>;

    /// The error for an input that ends inside the record at `at`.
    fn truncated(&self, at: u64) -> Self::Error;

    /// What the record at `at` carries, if anything: `record` holds its first
    /// `min(len, MAX_RECORD)` bytes.
    fn item<'a>(
        &mut self,
        record: &'a [u8],
        at: u64,
        len: u64,
    ) -> Result<Option<Self::Item<'a>>, Self::Error>;

    /// An item as a unit of MAVLink bytes.
    fn unit<'a>(item: Self::Item<'a>) -> Unit<'a>;

    /// Records passed over so far as carrying nothing this reader reads (packets that
    /// are not IPv4/UDP, or of a link type it does not know).
    fn passed_over(&self) -> u64 {
        0
    }
}

/// Iterator over the items of a capture held in memory. After an error it stops.
#[derive(Debug, Clone)]
pub struct Records<'a, F> {
    data: &'a [u8],
    pos: usize,
    format: F,
    failed: bool,
}

impl<'a, F: RecordFormat> Records<'a, F> {
    /// Walks `data` from `pos` (after any file header) with `format`.
    pub(crate) fn starting_at(data: &'a [u8], pos: usize, format: F) -> Self {
        Records {
            data,
            pos,
            format,
            failed: false,
        }
    }

    /// The format's state (counts of what was passed over, for instance).
    pub fn format(&self) -> &F {
        &self.format
    }
}

impl<'a, F: RecordFormat> Iterator for Records<'a, F> {
    type Item = Result<F::Item<'a>, F::Error>;

    fn next(&mut self) -> Option<Self::Item> {
        while !self.failed && self.pos < self.data.len() {
            let at = self.pos;
            let rest = &self.data[at..];
            let head = &rest[..rest.len().min(F::HEAD)];
            let step =
                self.format.record_len(head, at as u64).and_then(|len| {
                    match usize::try_from(len).ok().filter(|l| *l <= rest.len()) {
                        Some(l) => Ok(l),
                        None => Err(self.format.truncated(at as u64)),
                    }
                });
            let len = match step {
                Ok(len) => len,
                Err(e) => {
                    self.failed = true;
                    return Some(Err(e));
                }
            };
            self.pos += len;
            let keep = len.min(MAX_RECORD);
            match self.format.item(&rest[..keep], at as u64, len as u64) {
                Ok(Some(item)) => return Some(Ok(item)),
                Ok(None) => {}
                Err(e) => {
                    self.failed = true;
                    return Some(Err(e));
                }
            }
        }
        None
    }
}
