//! Batched UDP sends for the benchmarks' load generators, made through [`sys`](super::sys),
//! the one module with `unsafe` code, so that no harness needs any. Not part of the
//! router's interface.

use std::io;
use std::net::{SocketAddr, UdpSocket};

use super::sys;

/// Most datagrams one [`DatagramSender::send`] hands to the kernel.
pub const MAX_BATCH: usize = sys::MAX_BATCH;

/// Sends batches of datagrams, each to its own destination, one system call a batch.
#[derive(Default)]
pub struct DatagramSender(sys::SendBatch);

impl DatagramSender {
    /// A sender with its headers allocated once.
    pub fn new() -> Self {
        Self::default()
    }

    /// Sends the first [`MAX_BATCH`] of `datagrams` (bytes, destination) without
    /// blocking: `sendmmsg`, or `sendto` for one. Returns how many were sent, always a
    /// prefix (`WouldBlock` when the socket took none).
    pub fn send<'a>(
        &mut self,
        socket: &UdpSocket,
        datagrams: impl IntoIterator<Item = (&'a [u8], SocketAddr)>,
    ) -> io::Result<usize> {
        let batch = datagrams.into_iter().map(|(bytes, to)| (to, bytes));
        sys::send_batch(socket, &mut self.0, batch, false)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    /// A batch reaches each destination in order, and the count says all were sent.
    #[test]
    fn a_batch_reaches_each_destination() {
        let a = UdpSocket::bind("127.0.0.1:0").expect("bind");
        let b = UdpSocket::bind("127.0.0.1:0").expect("bind");
        let out = UdpSocket::bind("127.0.0.1:0").expect("bind");
        for s in [&a, &b] {
            s.set_read_timeout(Some(Duration::from_secs(5)))
                .expect("timeout");
        }
        let (to_a, to_b) = (a.local_addr().expect("addr"), b.local_addr().expect("addr"));
        let batch: [(&[u8], SocketAddr); 3] = [(b"one", to_a), (b"two", to_b), (b"three", to_a)];
        let mut sender = DatagramSender::new();
        assert_eq!(sender.send(&out, batch).expect("send"), 3);
        assert_eq!(
            sender
                .send(&out, batch.into_iter().take(1))
                .expect("send one"),
            1
        );
        let mut buf = [0u8; 16];
        let mut got = |s: &UdpSocket| {
            let n = s.recv(&mut buf).expect("a datagram within 5 s");
            buf[..n].to_vec()
        };
        assert_eq!(got(&a), b"one");
        assert_eq!(got(&a), b"three");
        assert_eq!(got(&a), b"one");
        assert_eq!(got(&b), b"two");
    }
}
