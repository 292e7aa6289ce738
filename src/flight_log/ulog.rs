//! PX4's ulog stream: numbered chunks of the log file (LOGGING_DATA, and
//! LOGGING_DATA_ACKED for the header and definitions, which the router acknowledges).
//! A lost chunk cannot be asked for again: the message it cut is dropped and the file
//! goes on at the next message start the following chunks name
//! (`first_message_offset`). Whole messages only reach the file. Pure.

use super::messages::UlogChunk;

/// Bytes of the ulog file header (magic, version, timestamp) before the first message.
pub(crate) const HEADER_LEN: usize = 16;
/// What every ulog file begins with (before its version byte).
const MAGIC: &[u8] = b"ULog\x01\x12\x35";
/// `first_message_offset` of a chunk in which no message starts.
const NO_MESSAGE_START: u8 = 255;
/// A ulog message's own header: size (u16) and type.
const MESSAGE_HEADER: usize = 3;

/// What one chunk gave.
#[derive(Debug, Default)]
pub(crate) struct UlogActs {
    /// Whole messages (and the file header) now in order.
    pub bytes: Vec<u8>,
    /// Chunks taken.
    pub chunks: u32,
    /// Chunks lost (by their sequence numbers).
    pub lost: u64,
    /// Chunks received twice.
    pub duplicates: u64,
    /// Chunks that came before the log's first one (the file header): not this log's.
    pub before_start: u64,
}

/// One ulog being received.
#[derive(Debug, Default)]
pub(crate) struct Ulog {
    /// The next sequence number expected (`None` before the first chunk).
    expected: Option<u16>,
    /// File header bytes still to come.
    header_left: usize,
    /// Bytes of a message not complete yet.
    partial: Vec<u8>,
    /// After a loss: chunks are skipped until one names where a message starts.
    syncing: bool,
}

impl Ulog {
    /// A log starting with its file header.
    pub(crate) fn new() -> Self {
        Ulog {
            header_left: HEADER_LEN,
            ..Ulog::default()
        }
    }

    /// True once a chunk was taken.
    pub(crate) fn started(&self) -> bool {
        self.expected.is_some()
    }

    /// The sequence number expected next, once a chunk was taken.
    pub(crate) fn expected(&self) -> Option<u16> {
        self.expected
    }

    /// Takes `chunk`. A log begins with the chunk that holds the file header: a chunk
    /// before it (of the log before, still on its way) is not taken, and starts nothing.
    pub(crate) fn chunk(&mut self, chunk: &UlogChunk, acts: &mut UlogActs) {
        if self.expected.is_none() && !chunk.data.starts_with(MAGIC) {
            acts.before_start += 1;
            return;
        }
        if let Some(expected) = self.expected {
            let ahead = chunk.sequence.wrapping_sub(expected);
            if ahead >= 0x8000 {
                // An older one: a resent chunk whose ACK was lost.
                acts.duplicates += 1;
                return;
            }
            if ahead > 0 {
                acts.lost += u64::from(ahead);
                self.partial.clear();
                self.syncing = true;
            }
        }
        self.expected = Some(chunk.sequence.wrapping_add(1));
        acts.chunks += 1;
        let mut data = chunk.data.as_slice();
        if self.syncing {
            if chunk.first_message_offset == NO_MESSAGE_START {
                return;
            }
            let at = usize::from(chunk.first_message_offset).min(data.len());
            data = &data[at..];
            self.syncing = false;
        }
        let header = self.header_left.min(data.len());
        acts.bytes.extend_from_slice(&data[..header]);
        self.header_left -= header;
        self.partial.extend_from_slice(&data[header..]);
        let mut at = 0;
        while let Some(size) = self.partial.get(at..at + 2) {
            let end = at + MESSAGE_HEADER + usize::from(u16::from_le_bytes([size[0], size[1]]));
            if end > self.partial.len() {
                break;
            }
            at = end;
        }
        acts.bytes.extend_from_slice(&self.partial[..at]);
        self.partial.drain(..at);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn chunk(sequence: u16, first_message_offset: u8, data: &[u8]) -> UlogChunk {
        UlogChunk {
            sequence,
            first_message_offset,
            data: data.to_vec(),
        }
    }

    fn message(kind: u8, body: &[u8]) -> Vec<u8> {
        let mut m = (body.len() as u16).to_le_bytes().to_vec();
        m.push(kind);
        m.extend_from_slice(body);
        m
    }

    fn header() -> [u8; HEADER_LEN] {
        let mut h = [7u8; HEADER_LEN];
        h[..MAGIC.len()].copy_from_slice(MAGIC);
        h
    }

    #[test]
    fn a_log_begins_with_its_header_and_nothing_before_it_is_taken() {
        let mut u = Ulog::new();
        let mut acts = UlogActs::default();
        let late = message(b'L', &[9; 6]);
        u.chunk(&chunk(812, 0, &late), &mut acts);
        assert_eq!((acts.before_start, acts.chunks, u.started()), (1, 0, false));
        let first = [header().as_slice(), &message(b'A', &[1; 3])].concat();
        u.chunk(&chunk(0, 16, &first), &mut acts);
        assert_eq!(acts.bytes, first);
        assert_eq!(u.expected(), Some(1));
    }

    #[test]
    fn whole_messages_only_and_a_lost_chunk_drops_the_message_it_cut() {
        let header = header();
        let a = message(b'A', &[1; 10]);
        let b = message(b'B', &[2; 10]);
        let c = message(b'C', &[3; 4]);
        let mut u = Ulog::new();
        let mut acts = UlogActs::default();
        let mut first = header.to_vec();
        first.extend_from_slice(&a);
        first.extend_from_slice(&b[..5]);
        u.chunk(&chunk(0, 16, &first), &mut acts);
        assert_eq!(acts.bytes.len(), HEADER_LEN + a.len());
        // Chunk 1 (the rest of b) is lost; chunk 2 starts with c.
        u.chunk(&chunk(2, 0, &c), &mut acts);
        assert_eq!(acts.lost, 1);
        let mut want = header.to_vec();
        want.extend_from_slice(&a);
        want.extend_from_slice(&c);
        assert_eq!(acts.bytes, want);
        u.chunk(&chunk(1, 0, &b[5..]), &mut acts);
        assert_eq!(acts.duplicates, 1);
    }
}
