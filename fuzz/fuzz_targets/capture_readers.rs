//! Arbitrary bytes never panic the capture readers, and the streaming reader, fed in
//! reads of arbitrary sizes (drawn from the input's first bytes), hands over exactly
//! the units the in-memory readers find, and stops with the same error.
#![no_main]

use std::io::Read;

use libfuzzer_sys::fuzz_target;
use mavtables::capture::records::{MAX_RECORD, RecordFormat};
use mavtables::capture::{Capture, CaptureError, Format, Unit, Units, pcap, pcapng, tlog};

/// Gives at most a few bytes per read, the counts taken in turn from `sizes`.
struct ShortReads<'a> {
    data: &'a [u8],
    sizes: &'a [u8],
    turn: usize,
}

impl Read for ShortReads<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let most = self
            .sizes
            .get(self.turn % self.sizes.len().max(1))
            .map_or(usize::MAX, |s| usize::from(*s) * 37 + 1);
        self.turn += 1;
        let n = most.min(buf.len()).min(self.data.len());
        buf[..n].copy_from_slice(&self.data[..n]);
        self.data = &self.data[n..];
        Ok(n)
    }
}

/// A unit, owned.
type Owned = (Option<u64>, u64, Vec<u8>, Option<([u8; 4], u16)>);

fn own(u: Unit<'_>) -> Owned {
    (u.timestamp_us, u.offset, u.bytes.to_vec(), u.source)
}

#[derive(Default)]
struct Collect(Vec<Owned>);

impl Units for Collect {
    fn unit(&mut self, unit: Unit<'_>) -> bool {
        self.0.push(own(unit));
        true
    }
}

/// Units and error of an in-memory walk.
fn walk<'a, F: RecordFormat + 'a>(
    items: impl Iterator<Item = Result<F::Item<'a>, F::Error>>,
) -> (Vec<Owned>, Option<CaptureError>)
where
    F::Error: Into<CaptureError>,
{
    let mut units = Vec::new();
    for item in items {
        match item {
            Ok(i) => units.push(own(F::unit(i))),
            Err(e) => return (units, Some(e.into())),
        }
    }
    (units, None)
}

fuzz_target!(|input: &[u8]| {
    let (sizes, data) = input.split_at(input.len().min(4));
    let capture = Capture::new(ShortReads { data, sizes, turn: 0 }).expect("in memory");
    let format = capture.format();
    let mut got = Collect::default();
    let end = capture.read(&mut got).expect("in memory");
    assert_eq!(end.bytes, data.len() as u64);
    assert!(!end.stopped);
    if data.len() > MAX_RECORD {
        return;
    }
    let expected = match format {
        Format::Raw => {
            assert_eq!(got.0.concat_bytes(), data);
            return;
        }
        Format::Tlog => walk::<tlog::Tlog>(tlog::records(data)),
        Format::Pcap => match pcap::Reader::new(data) {
            Ok(r) => walk::<pcap::Pcap>(r),
            Err(e) => (Vec::new(), Some(e.into())),
        },
        Format::PcapNg => match pcapng::Reader::new(data) {
            Ok(r) => walk::<pcapng::PcapNg>(r),
            Err(e) => (Vec::new(), Some(e.into())),
        },
    };
    assert_eq!((got.0, end.error), expected);
});

trait ConcatBytes {
    fn concat_bytes(&self) -> Vec<u8>;
}

impl ConcatBytes for Vec<Owned> {
    /// The raw pieces joined, each at the offset it claims.
    fn concat_bytes(&self) -> Vec<u8> {
        let mut out = Vec::new();
        for (_, offset, bytes, _) in self {
            assert_eq!(*offset, out.len() as u64, "raw pieces follow each other");
            out.extend(bytes);
        }
        out
    }
}
