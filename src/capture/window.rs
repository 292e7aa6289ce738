//! A bounded read buffer over any [`Read`]: holds the bytes of the record being read (and
//! whatever the last read brought beyond it), never more than its fixed capacity, so a
//! capture of any size is read in constant memory. Each read takes what the input has
//! (a pipe gives what has arrived), so nothing waits for a buffer to fill.

use std::io::{self, Read};

/// The bytes held from `input`, and where they are in it.
pub(crate) struct Window<R> {
    input: R,
    buf: Box<[u8]>,
    /// Held bytes are `buf[start..end]`.
    start: usize,
    end: usize,
    /// Input offset of `buf[start]`.
    offset: u64,
    /// The input has said it has no more bytes.
    eof: bool,
}

impl<R: Read> Window<R> {
    /// A window of `capacity` bytes over `input`.
    pub(crate) fn new(input: R, capacity: usize) -> Self {
        Window {
            input,
            buf: vec![0; capacity].into_boxed_slice(),
            start: 0,
            end: 0,
            offset: 0,
            eof: false,
        }
    }

    /// The bytes held, starting at input offset [`Window::offset`].
    pub(crate) fn bytes(&self) -> &[u8] {
        &self.buf[self.start..self.end]
    }

    /// Input offset of the first held byte.
    pub(crate) fn offset(&self) -> u64 {
        self.offset
    }

    /// Reads once from the input, after calling `waiting` (the read may wait for bytes
    /// to arrive). Returns how many bytes came: 0 at the end of the input, or when the
    /// window is full.
    pub(crate) fn read_more(&mut self, waiting: &mut impl FnMut()) -> io::Result<usize> {
        if self.eof {
            return Ok(0);
        }
        if self.end == self.buf.len() {
            self.buf.copy_within(self.start..self.end, 0);
            self.end -= self.start;
            self.start = 0;
        }
        if self.end == self.buf.len() {
            return Ok(0);
        }
        waiting();
        loop {
            match self.input.read(&mut self.buf[self.end..]) {
                Ok(0) => {
                    self.eof = true;
                    return Ok(0);
                }
                Ok(n) => {
                    self.end += n;
                    return Ok(n);
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
    }

    /// Reads until at least `n` bytes (at most the capacity) are held. False if the
    /// input ended first.
    pub(crate) fn fill_to(&mut self, n: usize, waiting: &mut impl FnMut()) -> io::Result<bool> {
        while self.end - self.start < n {
            if self.read_more(waiting)? == 0 {
                return Ok(false);
            }
        }
        Ok(true)
    }

    /// Drops the `n` input bytes that follow the first `keep` held bytes, reading them
    /// from the input as needed; the first `keep` stay held. False if the input ended
    /// before all `n` were seen. Afterwards [`Window::consume`] of `keep` bytes must be
    /// told `keep + n` as the input length they stand for.
    pub(crate) fn discard_after(
        &mut self,
        keep: usize,
        mut n: u64,
        waiting: &mut impl FnMut(),
    ) -> io::Result<bool> {
        let cut = self.start + keep;
        let beyond = (self.end - cut) as u64;
        if beyond >= n {
            // `n` fits in what is held: close the gap over it.
            let n = n as usize;
            self.buf.copy_within(cut + n..self.end, cut);
            self.end -= n;
            return Ok(true);
        }
        n -= beyond;
        self.end = cut;
        // Read the rest into the free space behind the kept bytes, never past `n`
        // (what follows belongs to the next record).
        if self.end == self.buf.len() {
            self.buf.copy_within(self.start..self.end, 0);
            self.end -= self.start;
            self.start = 0;
        }
        while n > 0 {
            if self.eof {
                return Ok(false);
            }
            let room = (self.buf.len() - self.end).min(usize::try_from(n).unwrap_or(usize::MAX));
            waiting();
            match self.input.read(&mut self.buf[self.end..self.end + room]) {
                Ok(0) => self.eof = true,
                Ok(got) => n -= got as u64,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
        Ok(true)
    }

    /// Lets go of the first `held` held bytes, which stand for `len` input bytes (more
    /// than `held` after [`Window::discard_after`]).
    pub(crate) fn consume(&mut self, held: usize, len: u64) {
        self.start += held;
        self.offset += len;
        if self.start == self.end {
            self.start = 0;
            self.end = 0;
        }
    }

    /// Reads the input to its end, dropping everything; returns the input's length.
    pub(crate) fn drain(&mut self, waiting: &mut impl FnMut()) -> io::Result<u64> {
        loop {
            let held = self.end - self.start;
            self.consume(held, held as u64);
            if self.read_more(waiting)? == 0 {
                return Ok(self.offset);
            }
        }
    }
}
