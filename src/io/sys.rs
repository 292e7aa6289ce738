//! The only `unsafe` code of mavtables: thin wrappers over the libc calls that the
//! standard library and mio do not offer.
//!
//! - `recvmmsg` / `sendmmsg`: receive or send a batch of UDP datagrams (IPv4 or IPv6)
//!   in one system call, sending runs
//!   of equal datagrams to one destination as one UDP GSO message (`UDP_SEGMENT`);
//!   `recvmsg` for a single datagram when traffic is light;
//! - `epoll_ctl`: a level-triggered watch, which mio does not offer;
//! - `SO_RCVBUFFORCE` / `SO_SNDBUFFORCE`: socket buffers beyond the system's limit
//!   when the process is privileged;
//! - `localtime_r`: the local calendar time for log lines and recording file names;
//! - `statvfs`: the free space of the disk recordings are written to;
//! - `SIOCOUTQ`: what a TCP socket sent that its peer has not acknowledged yet (a
//!   socket is closed only once nothing is, see `Driver::shut_write`);
//! - `geteuid`: the user whose files the recorder may remove;
//! - `timerfd`: a wake-up with microsecond precision for `max_bitrate` pacing (epoll's
//!   own timeout has millisecond granularity);
//! - turning a configured serial port into a non-blocking file for the event loop, and
//!   asking its driver for low latency (`TIOCSSERIAL` with `ASYNC_LOW_LATENCY`).
//!
//! Every function checks its inputs so that the pointers handed to the kernel always
//! describe memory owned by the caller for the duration of the call. Every `unsafe`
//! block says why it is sound in a `SAFETY:` comment (clippy enforces it).
#![warn(clippy::undocumented_unsafe_blocks)]

use std::io;
use std::mem::MaybeUninit;
use std::net::{Ipv4Addr, Ipv6Addr, SocketAddr, SocketAddrV4, SocketAddrV6};
use std::os::fd::{AsRawFd, RawFd};

/// Largest batch handed to one `recvmmsg` / `sendmmsg` call.
pub(super) const MAX_BATCH: usize = 64;

/// Room for an IPv4 or IPv6 socket address as the kernel reads and writes it.
type RawAddr = libc::sockaddr_in6;

const RAW_ADDR_LEN: libc::socklen_t = std::mem::size_of::<RawAddr>() as _;

/// Writes `addr` into `raw` the way the kernel reads it; returns its length.
fn to_raw(addr: SocketAddr, raw: &mut RawAddr) -> libc::socklen_t {
    match addr {
        SocketAddr::V4(a) => {
            // SAFETY: sockaddr_in is plain old data; all-zero is a valid value.
            let mut sa: libc::sockaddr_in = unsafe { MaybeUninit::zeroed().assume_init() };
            sa.sin_family = libc::AF_INET as libc::sa_family_t;
            sa.sin_port = a.port().to_be();
            sa.sin_addr = libc::in_addr {
                s_addr: u32::from(*a.ip()).to_be(),
            };
            // SAFETY: a sockaddr_in (16 bytes, alignment 4) fits at the start of a
            // sockaddr_in6 (28 bytes, alignment 4), which `raw` exclusively borrows.
            unsafe { std::ptr::write((raw as *mut RawAddr).cast::<libc::sockaddr_in>(), sa) };
            std::mem::size_of::<libc::sockaddr_in>() as _
        }
        SocketAddr::V6(a) => {
            // SAFETY: sockaddr_in6 is plain old data; all-zero is a valid value.
            let mut sa: libc::sockaddr_in6 = unsafe { MaybeUninit::zeroed().assume_init() };
            sa.sin6_family = libc::AF_INET6 as libc::sa_family_t;
            sa.sin6_port = a.port().to_be();
            sa.sin6_flowinfo = a.flowinfo();
            sa.sin6_addr = libc::in6_addr {
                s6_addr: a.ip().octets(),
            };
            sa.sin6_scope_id = a.scope_id();
            *raw = sa;
            RAW_ADDR_LEN
        }
    }
}

/// The address the kernel wrote into `raw`. An IPv4 peer of an IPv6 socket
/// (`::ffff:a.b.c.d`) is given as the IPv4 address, so that a peer has one name.
fn from_raw(raw: &RawAddr) -> Option<SocketAddr> {
    if raw.sin6_family == libc::AF_INET as libc::sa_family_t {
        // SAFETY: the kernel wrote a sockaddr_in (family AF_INET) at the start of `raw`,
        // which is large and aligned enough for one.
        let sa: libc::sockaddr_in =
            unsafe { std::ptr::read((raw as *const RawAddr).cast::<libc::sockaddr_in>()) };
        return Some(SocketAddr::V4(SocketAddrV4::new(
            Ipv4Addr::from(u32::from_be(sa.sin_addr.s_addr)),
            u16::from_be(sa.sin_port),
        )));
    }
    if raw.sin6_family == libc::AF_INET6 as libc::sa_family_t {
        let ip = Ipv6Addr::from(raw.sin6_addr.s6_addr);
        let port = u16::from_be(raw.sin6_port);
        return Some(match ip.to_ipv4_mapped() {
            Some(v4) => SocketAddr::V4(SocketAddrV4::new(v4, port)),
            None => SocketAddr::V6(SocketAddrV6::new(
                ip,
                port,
                raw.sin6_flowinfo,
                raw.sin6_scope_id,
            )),
        });
    }
    None
}

/// The C structures a `recvmmsg` call reads and writes, kept from call to call.
struct RecvHeaders {
    names: [RawAddr; MAX_BATCH],
    iovs: [libc::iovec; MAX_BATCH],
    msgs: [libc::mmsghdr; MAX_BATCH],
}

/// Receive buffers for [`recv_batch`]: `MAX_BATCH` slots of `slot_len` bytes, and the
/// headers that describe them to the kernel. The headers are set up once, so that a call
/// that reads one datagram does not first write 6 KiB of them.
pub(super) struct RecvBatch {
    data: Vec<u8>,
    slot_len: usize,
    headers: Box<RecvHeaders>,
    lens: [usize; MAX_BATCH],
    addrs: [Option<SocketAddr>; MAX_BATCH],
    /// Bytes read of the datagrams of the last call that were longer than their slot.
    cut: usize,
    count: usize,
}

impl RecvBatch {
    /// Buffers for datagrams of up to `slot_len` bytes (longer ones are truncated).
    pub(super) fn new(slot_len: usize) -> Self {
        let mut data = vec![0u8; slot_len * MAX_BATCH];
        // SAFETY: arrays of plain-old-data C structs; all-zero is a valid value.
        let mut headers: Box<RecvHeaders> =
            Box::new(unsafe { MaybeUninit::zeroed().assume_init() });
        let h = &mut *headers;
        let base = data.as_mut_ptr();
        for i in 0..MAX_BATCH {
            // Heap addresses: they stay valid when the `RecvBatch` moves, and `data` is
            // never resized.
            h.iovs[i].iov_base = base.wrapping_add(i * slot_len).cast();
            h.iovs[i].iov_len = slot_len;
            h.msgs[i].msg_hdr.msg_name = (&mut h.names[i] as *mut RawAddr).cast();
            h.msgs[i].msg_hdr.msg_namelen = RAW_ADDR_LEN;
            h.msgs[i].msg_hdr.msg_iov = &mut h.iovs[i];
            h.msgs[i].msg_hdr.msg_iovlen = 1;
        }
        RecvBatch {
            data,
            slot_len,
            headers,
            lens: [0; MAX_BATCH],
            addrs: [None; MAX_BATCH],
            cut: 0,
            count: 0,
        }
    }

    /// Datagrams received by the last call: (sender, bytes). The sender is `None` for
    /// one that is neither IPv4 nor IPv6, and for one longer than its slot, which is
    /// not to be handed on (see [`RecvBatch::cut_bytes`]).
    pub(super) fn iter(&self) -> impl Iterator<Item = (Option<SocketAddr>, &[u8])> {
        (0..self.count).map(move |i| {
            let start = i * self.slot_len;
            (self.addrs[i], &self.data[start..start + self.lens[i]])
        })
    }

    /// The bytes received of the datagrams of the last call that were longer than a
    /// slot: the kernel dropped the rest, so they are not handed on (a frame cut there
    /// would be joined to the next datagram's bytes).
    pub(super) fn cut_bytes(&self) -> usize {
        self.cut
    }
}

/// Receives up to [`MAX_BATCH`] datagrams without blocking. Returns how many arrived
/// (`WouldBlock` when none were waiting).
pub(super) fn recv_batch(fd: &impl AsRawFd, batch: &mut RecvBatch) -> io::Result<usize> {
    let fd: RawFd = fd.as_raw_fd();
    let h = &mut *batch.headers;
    // The kernel wrote the address lengths of the datagrams of the last call.
    for m in &mut h.msgs[..batch.count] {
        m.msg_hdr.msg_namelen = RAW_ADDR_LEN;
    }
    // SAFETY: every header points at its own entry of `names` and `iovs` (in the same
    // box) and at its own `slot_len` bytes of `data`, all owned by `batch`, which is
    // borrowed exclusively for the call; `data` has `MAX_BATCH * slot_len` bytes.
    let n = unsafe {
        libc::recvmmsg(
            fd,
            h.msgs.as_mut_ptr(),
            MAX_BATCH as libc::c_uint,
            libc::MSG_DONTWAIT,
            std::ptr::null_mut(),
        )
    };
    batch.cut = 0;
    if n < 0 {
        batch.count = 0;
        return Err(io::Error::last_os_error());
    }
    let n = n as usize;
    for i in 0..n {
        batch.lens[i] = (h.msgs[i].msg_len as usize).min(batch.slot_len);
        batch.addrs[i] = from_raw(&h.names[i]);
        if h.msgs[i].msg_hdr.msg_flags & libc::MSG_TRUNC != 0 {
            batch.addrs[i] = None;
            batch.cut += batch.lens[i];
        }
    }
    batch.count = n;
    Ok(n)
}

/// Receives one datagram without blocking into the first slot of `batch` (`recvmsg`):
/// one system call, where [`recv_batch`] also looks for a second datagram. For a socket
/// the loop watches level-triggered, whose next wake-up reports what is left. Returns 1
/// (`WouldBlock` when nothing was waiting); [`RecvBatch::iter`] gives the datagram.
pub(super) fn recv_one(fd: &impl AsRawFd, batch: &mut RecvBatch) -> io::Result<usize> {
    let fd: RawFd = fd.as_raw_fd();
    let h = &mut *batch.headers;
    h.msgs[0].msg_hdr.msg_namelen = RAW_ADDR_LEN;
    // SAFETY: the first header points at `names[0]`, `iovs[0]` and the first `slot_len`
    // bytes of `data`, all owned by `batch`, which is borrowed exclusively for the call.
    let n = unsafe { libc::recvmsg(fd, &mut h.msgs[0].msg_hdr, libc::MSG_DONTWAIT) };
    batch.cut = 0;
    if n < 0 {
        batch.count = 0;
        return Err(io::Error::last_os_error());
    }
    batch.lens[0] = (n as usize).min(batch.slot_len);
    batch.addrs[0] = from_raw(&h.names[0]);
    if h.msgs[0].msg_hdr.msg_flags & libc::MSG_TRUNC != 0 {
        batch.addrs[0] = None;
        batch.cut = batch.lens[0];
    }
    batch.count = 1;
    Ok(1)
}

/// Turns the watch of `fd` (registered by mio in `epoll` under `token`, edge-triggered)
/// level-triggered: readable (and writable, with `writable`) is reported at every wait
/// while it holds, not only when it changes, so a driver may end its turn before the
/// socket is drained. mio has no level-triggered registration of its own; it reads
/// back the token and the flags it knows, so the watch stays its to change or remove.
pub(super) fn watch_level_triggered(
    epoll: RawFd,
    fd: RawFd,
    token: usize,
    writable: bool,
) -> io::Result<()> {
    let mut events = libc::EPOLLIN | libc::EPOLLRDHUP;
    if writable {
        events |= libc::EPOLLOUT;
    }
    let mut event = libc::epoll_event {
        events: events as u32,
        u64: token as u64,
    };
    // SAFETY: passes a pointer to a live `epoll_event`; the kernel only reads it.
    let r = unsafe { libc::epoll_ctl(epoll, libc::EPOLL_CTL_MOD, fd, &mut event) };
    if r == 0 {
        Ok(())
    } else {
        Err(io::Error::last_os_error())
    }
}

/// Asks for a socket buffer of `bytes` beyond the system's limit
/// (`net.core.rmem_max` / `wmem_max`): `SO_RCVBUFFORCE` or `SO_SNDBUFFORCE`, which only a
/// process with `CAP_NET_ADMIN` may use. Fails with `EPERM` otherwise.
pub(super) fn force_buffer_size(fd: &impl AsRawFd, receive: bool, bytes: usize) -> io::Result<()> {
    let option = if receive {
        libc::SO_RCVBUFFORCE
    } else {
        libc::SO_SNDBUFFORCE
    };
    let value = libc::c_int::try_from(bytes).unwrap_or(libc::c_int::MAX);
    // SAFETY: passes a pointer to a live c_int and its size.
    let r = unsafe {
        libc::setsockopt(
            fd.as_raw_fd(),
            libc::SOL_SOCKET,
            option,
            (&value as *const libc::c_int).cast(),
            std::mem::size_of::<libc::c_int>() as libc::socklen_t,
        )
    };
    if r == 0 {
        Ok(())
    } else {
        Err(io::Error::last_os_error())
    }
}

/// `UDP_SEGMENT` (linux/udp.h): the socket option and control message of UDP GSO
/// (Linux 4.18). Defined here because not every libc target exports it.
const UDP_SEGMENT: libc::c_int = 103;

/// Most datagrams in one GSO message. The kernel takes 64 (`UDP_MAX_SEGMENTS` before
/// Linux 6.9, 128 after); one batch never holds more than [`MAX_BATCH`] anyway.
const GSO_MAX_SEGMENTS: usize = 64;

/// Most bytes in one GSO message: an IPv4 datagram's payload is at most 65,507 bytes.
const GSO_MAX_BYTES: usize = 65_000;

/// Room for one control message carrying a `u16` (`CMSG_SPACE(2)` is 24 bytes on
/// 64-bit Linux), kept in `u64`s so that it is aligned for `cmsghdr`.
type CmsgBuf = [u64; 4];

/// True if the kernel offers UDP GSO (`UDP_SEGMENT`) on this socket. A kernel without
/// it would not refuse the control message but ignore it, and send the whole run as a
/// single datagram, so GSO is only used where this says yes.
pub(super) fn gso_supported(fd: &impl AsRawFd) -> bool {
    let mut value: libc::c_int = 0;
    let mut len = std::mem::size_of::<libc::c_int>() as libc::socklen_t;
    // SAFETY: both pointers are to live locals of the sizes given.
    let r = unsafe {
        libc::getsockopt(
            fd.as_raw_fd(),
            libc::SOL_UDP,
            UDP_SEGMENT,
            (&mut value as *mut libc::c_int).cast(),
            &mut len,
        )
    };
    r == 0
}

/// Sends `datagrams` (destination, bytes) without blocking, as many as the kernel takes
/// in one `sendmmsg` call. Returns how many datagrams were sent (`WouldBlock` when none
/// could be).
///
/// With `gso`, each run of consecutive datagrams to the same destination and of the same
/// length (the run's last may be shorter) goes to the kernel as one UDP GSO message: it
/// travels the IP stack once and is cut back into exactly the same datagrams on the way
/// out (by the network card, the driver, or on loopback the receiving socket). The peer
/// receives what it would have without GSO; the router pays one send instead of many.
/// When the kernel or the route refuses a GSO run (`EIO` or `EINVAL` for a message of
/// several datagrams), the error comes back as [`io::ErrorKind::Unsupported`]: call
/// again without GSO.
pub(super) fn send_batch<'a>(
    fd: &impl AsRawFd,
    batch: &mut SendBatch,
    datagrams: impl IntoIterator<Item = (SocketAddr, &'a [u8])>,
    gso: bool,
) -> io::Result<usize> {
    let h = &mut *batch.0;
    let mut n = 0;
    for (i, (addr, bytes)) in datagrams.into_iter().take(MAX_BATCH).enumerate() {
        n = i + 1;
        h.lens[i] = to_raw(addr, &mut h.names[i]);
        h.addrs[i] = addr;
        // The kernel only reads through this pointer (sendmmsg).
        h.iovs[i].iov_base = bytes.as_ptr() as *mut libc::c_void;
        h.iovs[i].iov_len = bytes.len();
    }
    if n == 0 {
        return Ok(0);
    }
    if n == 1 {
        return send_one(fd.as_raw_fd(), h);
    }
    // Group the datagrams into messages, each a run from datagram `i` to `end`.
    let mut messages = 0;
    let mut i = 0;
    while i < n {
        let size = h.iovs[i].iov_len;
        let mut end = i + 1;
        let mut total = size;
        while gso
            && end < n
            && h.addrs[end] == h.addrs[i]
            && h.iovs[end].iov_len <= size
            && h.iovs[end].iov_len > 0
            && end - i < GSO_MAX_SEGMENTS
            && total + h.iovs[end].iov_len <= GSO_MAX_BYTES
        {
            total += h.iovs[end].iov_len;
            end += 1;
            if h.iovs[end - 1].iov_len < size {
                break; // a shorter datagram can only end a run
            }
        }
        let run = end - i;
        let hdr = &mut h.msgs[messages].msg_hdr;
        hdr.msg_name = (&mut h.names[i] as *mut RawAddr).cast();
        hdr.msg_namelen = h.lens[i];
        hdr.msg_iov = &mut h.iovs[i];
        hdr.msg_iovlen = run as _;
        hdr.msg_flags = 0;
        if run > 1 {
            hdr.msg_control = h.cmsgs[messages].as_mut_ptr().cast();
            // SAFETY: CMSG_SPACE only computes a size.
            hdr.msg_controllen = unsafe { libc::CMSG_SPACE(2) } as _;
            // SAFETY: the control buffer set just above is 32 bytes, aligned for
            // `cmsghdr`, and holds CMSG_SPACE(2) = 24 bytes, so the first header and its
            // two data bytes lie inside it.
            unsafe {
                let c = libc::CMSG_FIRSTHDR(hdr);
                (*c).cmsg_level = libc::SOL_UDP;
                (*c).cmsg_type = UDP_SEGMENT;
                (*c).cmsg_len = libc::CMSG_LEN(2) as _;
                std::ptr::write_unaligned(libc::CMSG_DATA(c).cast::<u16>(), size as u16);
            }
        } else {
            hdr.msg_control = std::ptr::null_mut();
            hdr.msg_controllen = 0;
        }
        messages += 1;
        i = end;
    }
    // SAFETY: the first `messages` headers were all written above; they point at entries
    // of `names`, `iovs` and `cmsgs` in the same box and, through `iovs`, at the borrowed
    // datagrams, all alive for the call; each message's iovecs are `msg_iovlen`
    // consecutive entries of the first `n` of `iovs`.
    let sent = unsafe {
        libc::sendmmsg(
            fd.as_raw_fd(),
            h.msgs.as_mut_ptr(),
            messages as libc::c_uint,
            libc::MSG_DONTWAIT,
        )
    };
    // `msg_iovlen` is a `size_t` with glibc and an `int` with musl.
    #[allow(clippy::unnecessary_cast)]
    let datagrams_of = |m: &libc::mmsghdr| m.msg_hdr.msg_iovlen as usize;
    if sent < 0 {
        let e = io::Error::last_os_error();
        // sendmmsg fails only when its first message does.
        if datagrams_of(&h.msgs[0]) > 1
            && matches!(e.raw_os_error(), Some(libc::EIO | libc::EINVAL))
        {
            return Err(io::Error::new(
                io::ErrorKind::Unsupported,
                format!("UDP segmentation offload refused: {e}"),
            ));
        }
        return Err(e);
    }
    Ok(h.msgs[..sent as usize].iter().map(datagrams_of).sum())
}

/// Sends the one datagram of a batch with `sendto`: at the rates vehicles send, most
/// batches hold one, and `sendto` spares the kernel the copies of the `sendmmsg`
/// headers and vector (one system call either way). Returns 1 once it is sent.
fn send_one(fd: RawFd, h: &SendHeaders) -> io::Result<usize> {
    // SAFETY: `iovs[0]` points at the borrowed datagram of `iov_len` bytes and
    // `names[0]` holds its destination's address of `lens[0]` bytes, all alive for the
    // call, which only reads them.
    let r = unsafe {
        libc::sendto(
            fd,
            h.iovs[0].iov_base,
            h.iovs[0].iov_len,
            libc::MSG_DONTWAIT,
            (&h.names[0] as *const RawAddr).cast(),
            h.lens[0],
        )
    };
    if r < 0 {
        return Err(io::Error::last_os_error());
    }
    Ok(1)
}

/// The C structures a `sendmmsg` call reads, kept from call to call like those of
/// [`RecvBatch`]; a call writes only the entries it uses.
struct SendHeaders {
    names: [RawAddr; MAX_BATCH],
    lens: [libc::socklen_t; MAX_BATCH],
    addrs: [SocketAddr; MAX_BATCH],
    iovs: [libc::iovec; MAX_BATCH],
    msgs: [libc::mmsghdr; MAX_BATCH],
    cmsgs: [CmsgBuf; MAX_BATCH],
}

/// Scratch space of [`send_batch`]: one per socket that sends.
pub(super) struct SendBatch(Box<SendHeaders>);

impl SendBatch {
    /// Empty headers.
    pub(super) fn new() -> Self {
        let mut headers = MaybeUninit::<SendHeaders>::zeroed();
        let unspecified = SocketAddr::from(([0u8; 4], 0));
        // SAFETY: every field but `addrs` is an array of plain-old-data C structs or
        // integers (null pointers included), for which all-zero bytes are valid values.
        // `addrs` holds Rust enums, whose layout is not specified, so it is written here
        // through a pointer to the field (no reference to uninitialised memory) before
        // the whole is taken as initialised.
        unsafe {
            let p = headers.as_mut_ptr();
            std::ptr::addr_of_mut!((*p).addrs).write([unspecified; MAX_BATCH]);
            SendBatch(Box::new(headers.assume_init()))
        }
    }
}

impl Default for SendBatch {
    fn default() -> Self {
        Self::new()
    }
}

/// Local calendar time of a UNIX time in seconds: (year, month 1–12, day, hour, minute,
/// second). `None` if the C library cannot convert it.
pub(super) fn local_time(unix_seconds: i64) -> Option<(i32, u32, u32, u32, u32, u32)> {
    let t: libc::time_t = unix_seconds;
    // SAFETY: `tm` is plain old data; localtime_r writes it and reads only `t`.
    let mut tm: libc::tm = unsafe { MaybeUninit::zeroed().assume_init() };
    // SAFETY: both pointers are to live locals.
    let r = unsafe { libc::localtime_r(&t, &mut tm) };
    if r.is_null() {
        return None;
    }
    Some((
        tm.tm_year + 1900,
        (tm.tm_mon + 1) as u32,
        tm.tm_mday as u32,
        tm.tm_hour as u32,
        tm.tm_min as u32,
        tm.tm_sec as u32,
    ))
}

/// The bytes an unprivileged process may still write on the file system holding `path`
/// (`statvfs`: available blocks times the fragment size).
pub(super) fn free_bytes(path: &std::path::Path) -> io::Result<u64> {
    use std::os::unix::ffi::OsStrExt;
    let c_path = std::ffi::CString::new(path.as_os_str().as_bytes())
        .map_err(|_| io::Error::new(io::ErrorKind::InvalidInput, "path holds a NUL byte"))?;
    // SAFETY: `statvfs` is plain old data; statvfs(3) fills it in.
    let mut st: libc::statvfs = unsafe { MaybeUninit::zeroed().assume_init() };
    // SAFETY: `c_path` is a NUL-terminated string and `st` a live local, both valid for
    // the duration of the call; the kernel reads the one and writes the other only.
    let rc = unsafe { libc::statvfs(c_path.as_ptr(), &mut st) };
    if rc != 0 {
        return Err(io::Error::last_os_error());
    }
    #[allow(clippy::useless_conversion)] // the field types differ between targets
    let (blocks, size) = (u64::from(st.f_bavail), u64::from(st.f_frsize));
    Ok(blocks.saturating_mul(size))
}

/// Bytes sent on stream socket `fd` that its peer has not acknowledged yet
/// (`SIOCOUTQ`): once none are, closing it loses nothing, whatever the peer sends next.
pub(super) fn unacknowledged_bytes(fd: &impl AsRawFd) -> io::Result<usize> {
    let mut n: libc::c_int = 0;
    // SAFETY: `SIOCOUTQ` (the same number as `TIOCOUTQ`) writes one `c_int` through the
    // pointer, which points at `n`, owned by this frame for the call; `fd` is borrowed.
    let r = unsafe { libc::ioctl(fd.as_raw_fd(), libc::TIOCOUTQ, &raw mut n) };
    if r < 0 {
        return Err(io::Error::last_os_error());
    }
    Ok(usize::try_from(n).unwrap_or(0))
}

/// The user the process acts as (`geteuid`): the owner of the files it creates, and
/// the only owner of recordings and of their list that the recorder believes.
pub(crate) fn effective_uid() -> u32 {
    // SAFETY: geteuid(2) takes no arguments, touches no memory and always succeeds.
    unsafe { libc::geteuid() }
}

/// `CLOCK_MONOTONIC` in microseconds: the clock systemd reads `MONOTONIC_USEC=` against.
pub(super) fn monotonic_micros() -> u64 {
    let mut t = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `t` is a live local the call writes to; CLOCK_MONOTONIC always exists.
    let r = unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut t) };
    if r != 0 {
        return 0;
    }
    let secs = u64::try_from(t.tv_sec).unwrap_or(0);
    let nanos = u64::try_from(t.tv_nsec).unwrap_or(0);
    secs.saturating_mul(1_000_000).saturating_add(nanos / 1_000)
}

/// A monotonic one-shot timer as a file descriptor that becomes readable when it fires.
pub(super) struct TimerFd {
    fd: std::os::fd::OwnedFd,
}

impl TimerFd {
    /// A disarmed, non-blocking timer on `CLOCK_MONOTONIC`.
    pub(super) fn new() -> io::Result<Self> {
        // SAFETY: plain system call with constant flags.
        let fd = unsafe {
            libc::timerfd_create(
                libc::CLOCK_MONOTONIC,
                libc::TFD_NONBLOCK | libc::TFD_CLOEXEC,
            )
        };
        if fd < 0 {
            return Err(io::Error::last_os_error());
        }
        // SAFETY: `fd` was just returned by the kernel and is owned by nobody else.
        let fd = unsafe { std::os::fd::FromRawFd::from_raw_fd(fd) };
        Ok(TimerFd { fd })
    }

    /// Fires once after `delay` (a zero delay fires at once); `None` disarms.
    pub(super) fn set(&self, delay: Option<std::time::Duration>) -> io::Result<()> {
        let mut value = libc::itimerspec {
            it_interval: libc::timespec {
                tv_sec: 0,
                tv_nsec: 0,
            },
            it_value: libc::timespec {
                tv_sec: 0,
                tv_nsec: 0,
            },
        };
        if let Some(d) = delay {
            // A zero it_value would disarm: fire after one nanosecond instead.
            let d = d.max(std::time::Duration::from_nanos(1));
            value.it_value.tv_sec = d.as_secs() as libc::time_t;
            value.it_value.tv_nsec = d.subsec_nanos() as libc::c_long;
        }
        // SAFETY: `value` is a live local; the old value is not wanted (null).
        let r =
            unsafe { libc::timerfd_settime(self.fd.as_raw_fd(), 0, &value, std::ptr::null_mut()) };
        if r < 0 {
            return Err(io::Error::last_os_error());
        }
        Ok(())
    }

    /// Clears a fired timer so it can fire again.
    pub(super) fn acknowledge(&self) {
        let mut expirations = [0u8; 8];
        // SAFETY: reads at most 8 bytes into a live local buffer; errors (EAGAIN when
        // it had not fired) are of no interest.
        let _ = unsafe { libc::read(self.fd.as_raw_fd(), expirations.as_mut_ptr().cast(), 8) };
    }
}

impl AsRawFd for TimerFd {
    fn as_raw_fd(&self) -> RawFd {
        self.fd.as_raw_fd()
    }
}

/// Takes over the file descriptor of a serial port configured by the `serialport` crate
/// (raw mode, baud rate, flow control) as a non-blocking [`std::fs::File`].
pub(super) fn nonblocking_file(port: serialport::TTYPort) -> io::Result<std::fs::File> {
    let fd = std::os::fd::IntoRawFd::into_raw_fd(port);
    // SAFETY: `into_raw_fd` hands over sole ownership of an open descriptor.
    let file = unsafe { <std::fs::File as std::os::fd::FromRawFd>::from_raw_fd(fd) };
    // SAFETY: fcntl on a descriptor we own (`file`), with integer arguments only.
    let flags = unsafe { libc::fcntl(fd, libc::F_GETFL) };
    if flags < 0 {
        return Err(io::Error::last_os_error());
    }
    // SAFETY: as above; F_SETFL takes the flags as an integer.
    if unsafe { libc::fcntl(fd, libc::F_SETFL, flags | libc::O_NONBLOCK) } < 0 {
        return Err(io::Error::last_os_error());
    }
    Ok(file)
}

/// `ASYNC_LOW_LATENCY` (linux/tty_flags.h): the serial driver hands received bytes on
/// at once instead of collecting them first (USB-serial adapters of FTDI make this their
/// 1 ms latency timer instead of 16 ms).
const ASYNC_LOW_LATENCY: libc::c_int = 1 << 13;

/// Byte offset of `flags` in the kernel's `struct serial_struct` (after the `int`s
/// `type`, `line`, `port` and `irq`).
const SERIAL_FLAGS_OFFSET: usize = 16;

/// Room for the kernel's `struct serial_struct` (72 bytes on 64-bit Linux) with margin,
/// aligned for its `int`s and pointers.
#[repr(C, align(8))]
struct SerialInfo([u8; 128]);

/// Asks the serial driver of `port` for low latency (`ASYNC_LOW_LATENCY`, which any user
/// may set), as mavlink-router does. Fails with `ENOTTY` or `EINVAL` where the device has
/// no such setting (a pseudo-terminal, some USB CDC devices); the port works either way.
pub(super) fn request_low_latency(port: &impl AsRawFd) -> io::Result<()> {
    let mut info = SerialInfo([0; 128]);
    let fd = port.as_raw_fd();
    // SAFETY: TIOCGSERIAL writes one `struct serial_struct`, which fits in `info`.
    if unsafe { libc::ioctl(fd, libc::TIOCGSERIAL, info.0.as_mut_ptr()) } < 0 {
        return Err(io::Error::last_os_error());
    }
    let at = SERIAL_FLAGS_OFFSET..SERIAL_FLAGS_OFFSET + 4;
    let mut flags = [0u8; 4];
    flags.copy_from_slice(&info.0[at.clone()]);
    let flags = libc::c_int::from_ne_bytes(flags);
    if flags & ASYNC_LOW_LATENCY != 0 {
        return Ok(());
    }
    info.0[at].copy_from_slice(&(flags | ASYNC_LOW_LATENCY).to_ne_bytes());
    // SAFETY: TIOCSSERIAL reads one `struct serial_struct` from `info`, as read above.
    if unsafe { libc::ioctl(fd, libc::TIOCSSERIAL, info.0.as_ptr()) } < 0 {
        return Err(io::Error::last_os_error());
    }
    Ok(())
}

/// Turns UDP checksums off on a socket (`SO_NO_CHECK`). UDP segmentation offload
/// needs checksum offload and refuses such sockets, so tests use it to see the GSO
/// fallback at work.
#[cfg(test)]
pub(crate) fn disable_udp_checksums(fd: &impl AsRawFd) -> io::Result<()> {
    let one: libc::c_int = 1;
    // SAFETY: passes a pointer to a live c_int and its size.
    let r = unsafe {
        libc::setsockopt(
            fd.as_raw_fd(),
            libc::SOL_SOCKET,
            libc::SO_NO_CHECK,
            (&one as *const libc::c_int).cast(),
            std::mem::size_of::<libc::c_int>() as libc::socklen_t,
        )
    };
    if r == 0 {
        Ok(())
    } else {
        Err(io::Error::last_os_error())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::net::UdpSocket;

    #[test]
    fn a_datagram_longer_than_its_slot_is_not_handed_on_but_counted() {
        let rx = UdpSocket::bind("127.0.0.1:0").expect("bind");
        let tx = UdpSocket::bind("127.0.0.1:0").expect("bind");
        let to = rx.local_addr().expect("addr");
        for (n, read_one) in [(3000, true), (3001, false)] {
            tx.send_to(&vec![7u8; n], to).expect("send");
            tx.send_to(&[1, 2, 3], to).expect("send");
            let mut batch = RecvBatch::new(2048);
            let (mut whole, mut cut) = (Vec::new(), 0);
            let deadline = std::time::Instant::now() + std::time::Duration::from_secs(5);
            while whole.is_empty() && std::time::Instant::now() < deadline {
                let got = match read_one {
                    true => recv_one(&rx, &mut batch),
                    false => recv_batch(&rx, &mut batch),
                };
                match got {
                    Ok(_) => {
                        cut += batch.cut_bytes();
                        whole.extend(
                            batch
                                .iter()
                                .filter_map(|(from, b)| from.map(|_| b.to_vec())),
                        );
                    }
                    Err(e) if e.kind() == io::ErrorKind::WouldBlock => std::thread::yield_now(),
                    Err(e) => panic!("recv: {e}"),
                }
            }
            assert_eq!(cut, 2048, "the part read of the long one");
            assert_eq!(whole, [vec![1, 2, 3]], "only the whole one");
        }
    }

    #[test]
    fn batches_round_trip_over_loopback() {
        let rx = UdpSocket::bind("127.0.0.1:0").expect("bind");
        let tx = UdpSocket::bind("127.0.0.1:0").expect("bind");
        let to = rx.local_addr().expect("addr");
        let payloads: Vec<Vec<u8>> = (0..10u8).map(|i| vec![i; 1 + i as usize]).collect();
        let dgs: Vec<(SocketAddr, &[u8])> = payloads.iter().map(|p| (to, p.as_slice())).collect();
        assert_eq!(
            send_batch(&tx, &mut SendBatch::new(), dgs.iter().copied(), false).expect("send"),
            10
        );
        let mut batch = RecvBatch::new(2048);
        let mut got = Vec::new();
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(5);
        while got.len() < 10 && std::time::Instant::now() < deadline {
            match recv_batch(&rx, &mut batch) {
                Ok(_) => got.extend(batch.iter().map(|(from, b)| (from, b.to_vec()))),
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => std::thread::yield_now(),
                Err(e) => panic!("recv: {e}"),
            }
        }
        let from = tx.local_addr().expect("addr");
        assert_eq!(got.len(), 10);
        for (i, (src, bytes)) in got.iter().enumerate() {
            assert_eq!(*src, Some(from));
            assert_eq!(bytes, &payloads[i]);
        }
        assert_eq!(
            recv_batch(&rx, &mut batch).err().map(|e| e.kind()),
            Some(io::ErrorKind::WouldBlock)
        );
    }

    /// A full batch says the socket may hold more; the next call takes the rest, in
    /// order, and says it is drained.
    #[test]
    fn a_full_batch_is_followed_by_the_rest() {
        let rx = UdpSocket::bind("127.0.0.1:0").expect("bind");
        let tx = UdpSocket::bind("127.0.0.1:0").expect("bind");
        let to = rx.local_addr().expect("addr");
        let mut batch = RecvBatch::new(16);
        let total = MAX_BATCH + 6;
        for i in 0..total {
            tx.send_to(&(i as u32).to_le_bytes(), to).expect("send");
        }
        let mut got = Vec::new();
        let mut counts = Vec::new();
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(5);
        while got.len() < total && std::time::Instant::now() < deadline {
            match recv_batch(&rx, &mut batch) {
                Ok(n) => {
                    counts.push(n);
                    got.extend(
                        batch
                            .iter()
                            .map(|(_, b)| u32::from_le_bytes(b.try_into().expect("4 bytes"))),
                    );
                }
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => std::thread::yield_now(),
                Err(e) => panic!("recv: {e}"),
            }
        }
        assert_eq!(got, (0..total as u32).collect::<Vec<_>>());
        assert_eq!(counts.first(), Some(&MAX_BATCH), "{counts:?}");
        assert!(counts[1..].iter().all(|&n| n < MAX_BATCH), "{counts:?}");
    }

    #[test]
    fn ipv6_batches_round_trip_and_v4_mapped_peers_read_as_ipv4() {
        // Not skipped where IPv6 is off: the router's IPv6 support is what this checks.
        let rx = UdpSocket::bind("[::]:0").expect(
            "IPv6 is needed for this test: enable it (sysctl -w net.ipv6.conf.all.disable_ipv6=0)",
        );
        let port = rx.local_addr().expect("addr").port();
        let tx6 = UdpSocket::bind("[::1]:0").expect("bind ::1");
        let tx4 = UdpSocket::bind("127.0.0.1:0").expect("bind");
        let to6: SocketAddr = format!("[::1]:{port}").parse().expect("addr");
        let to4: SocketAddr = format!("127.0.0.1:{port}").parse().expect("addr");
        let sent6 = send_batch(&tx6, &mut SendBatch::new(), [(to6, &b"six"[..])], false);
        assert_eq!(sent6.expect("send over IPv6"), 1);
        let sent4 = send_batch(&tx4, &mut SendBatch::new(), [(to4, &b"four"[..])], false);
        assert_eq!(sent4.expect("send over IPv4"), 1);
        rx.set_nonblocking(true).expect("nonblocking");
        let mut batch = RecvBatch::new(64);
        let mut got = Vec::new();
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(5);
        while got.len() < 2 && std::time::Instant::now() < deadline {
            if recv_batch(&rx, &mut batch).is_ok() {
                got.extend(batch.iter().map(|(from, b)| (from, b.to_vec())));
            }
        }
        got.sort_by_key(|(_, b)| b.clone());
        assert_eq!(
            got,
            [
                (tx4.local_addr().ok(), b"four".to_vec()),
                (tx6.local_addr().ok(), b"six".to_vec())
            ]
        );
    }

    #[test]
    fn low_latency_is_refused_by_a_pty_without_harm() {
        let (mut master, mut slave) = (0, 0);
        // SAFETY: openpty writes two descriptors; the name, termios and size are optional.
        let r = unsafe {
            libc::openpty(
                &mut master,
                &mut slave,
                std::ptr::null_mut(),
                std::ptr::null(),
                std::ptr::null(),
            )
        };
        assert_eq!(r, 0, "openpty: {}", io::Error::last_os_error());
        // SAFETY: both descriptors were just opened and are owned by nobody else.
        let (master, slave) = unsafe {
            use std::os::fd::FromRawFd;
            (
                std::fs::File::from_raw_fd(master),
                std::fs::File::from_raw_fd(slave),
            )
        };
        let e = request_low_latency(&slave).expect_err("a pty has no serial settings");
        assert_eq!(e.raw_os_error(), Some(libc::ENOTTY));
        // The terminal still carries bytes.
        use std::io::{Read, Write};
        (&slave).write_all(b"ok").expect("write");
        let mut buf = [0u8; 2];
        (&master).read_exact(&mut buf).expect("read");
        assert_eq!(&buf, b"ok");
    }

    fn v4(s: &UdpSocket) -> SocketAddr {
        s.local_addr().expect("addr")
    }

    /// Every datagram waiting on `rx`, in order (waits up to 5 s for `want`).
    fn drain(rx: &UdpSocket, want: usize) -> Vec<Vec<u8>> {
        let mut batch = RecvBatch::new(2048);
        let mut got = Vec::new();
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(5);
        while got.len() < want && std::time::Instant::now() < deadline {
            match recv_batch(rx, &mut batch) {
                Ok(_) => got.extend(batch.iter().map(|(_, b)| b.to_vec())),
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => std::thread::yield_now(),
                Err(e) => panic!("recv: {e}"),
            }
        }
        got
    }

    #[test]
    fn gso_batches_arrive_as_the_same_datagrams_in_order() {
        let tx = UdpSocket::bind("127.0.0.1:0").expect("bind");
        let rx = [
            UdpSocket::bind("127.0.0.1:0").expect("bind"),
            UdpSocket::bind("127.0.0.1:0").expect("bind"),
        ];
        rx.iter()
            .for_each(|s| s.set_nonblocking(true).expect("nonblocking"));
        let to = [v4(&rx[0]), v4(&rx[1])];
        // Runs of equal lengths, runs ended by a shorter datagram, a longer one after a
        // shorter one, alternating destinations, one datagram alone: every way a run
        // can start and end. Each payload is unique so order and cuts are visible.
        let plan: [(usize, usize); 16] = [
            (0, 30),
            (0, 30),
            (0, 30),
            (0, 12),
            (0, 40),
            (0, 40),
            (1, 40),
            (1, 40),
            (0, 40),
            (1, 280),
            (1, 280),
            (1, 279),
            (1, 280),
            (0, 20),
            (0, 20),
            (0, 20),
        ];
        let payloads: Vec<Vec<u8>> = plan
            .iter()
            .enumerate()
            .map(|(i, &(_, len))| (0..len).map(|k| (i * 7 + k) as u8).collect())
            .collect();
        let dgs: Vec<(SocketAddr, &[u8])> = plan
            .iter()
            .zip(&payloads)
            .map(|(&(r, _), p)| (to[r], p.as_slice()))
            .collect();
        let gso = gso_supported(&tx);
        let sent = send_batch(&tx, &mut SendBatch::new(), dgs.iter().copied(), gso).expect("send");
        assert_eq!(sent, plan.len(), "gso = {gso}");
        for (r, rx) in rx.iter().enumerate() {
            let want: Vec<Vec<u8>> = plan
                .iter()
                .zip(&payloads)
                .filter(|((d, _), _)| *d == r)
                .map(|(_, p)| p.clone())
                .collect();
            assert_eq!(drain(rx, want.len()), want, "receiver {r}, gso = {gso}");
        }
    }

    #[test]
    fn long_gso_runs_arrive_whole() {
        let tx = UdpSocket::bind("127.0.0.1:0").expect("bind");
        let rx = UdpSocket::bind("127.0.0.1:0").expect("bind");
        rx.set_nonblocking(true).expect("nonblocking");
        let to = v4(&rx);
        for (count, len) in [(16usize, 21usize), (64, 21), (64, 22), (40, 280)] {
            let payloads: Vec<Vec<u8>> = (0..count)
                .map(|i| (0..len).map(|k| (i * 3 + k) as u8).collect())
                .collect();
            let dgs: Vec<(SocketAddr, &[u8])> =
                payloads.iter().map(|p| (to, p.as_slice())).collect();
            let sent = send_batch(
                &tx,
                &mut SendBatch::new(),
                dgs.iter().copied(),
                gso_supported(&tx),
            )
            .expect("send");
            assert_eq!(sent, count);
            assert_eq!(drain(&rx, count), payloads, "{count} x {len}");
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]
        /// Any batch, cut into GSO runs however it falls, reaches each receiver as the
        /// same datagrams in the same order.
        #[test]
        fn any_batch_arrives_unchanged(
            plan in proptest::collection::vec(
                (
                    // Few destinations and few lengths, so that runs of every kind form.
                    proptest::sample::select(vec![0usize, 0, 0, 1, 2]),
                    proptest::sample::select(vec![1usize, 12, 21, 22, 40, 279, 280]),
                    proptest::prelude::any::<u8>(),
                ),
                1..=MAX_BATCH,
            )
        ) {
            let tx = UdpSocket::bind("127.0.0.1:0").expect("bind");
            let rx: Vec<UdpSocket> = (0..3).map(|_| UdpSocket::bind("127.0.0.1:0").expect("bind")).collect();
            rx.iter().for_each(|s| s.set_nonblocking(true).expect("nonblocking"));
            let to: Vec<SocketAddr> = rx.iter().map(v4).collect();
            let payloads: Vec<Vec<u8>> = plan
                .iter()
                .map(|&(_, len, seed)| (0..len).map(|k| seed.wrapping_add(k as u8)).collect())
                .collect();
            let dgs: Vec<(SocketAddr, &[u8])> =
                plan.iter().zip(&payloads).map(|(&(r, _, _), p)| (to[r], p.as_slice())).collect();
            let mut sent = 0;
            while sent < dgs.len() {
                sent += send_batch(&tx, &mut SendBatch::new(), dgs[sent..].iter().copied(), gso_supported(&tx)).expect("send");
            }
            for (r, rx) in rx.iter().enumerate() {
                let want: Vec<Vec<u8>> = plan
                    .iter()
                    .zip(&payloads)
                    .filter(|((d, _, _), _)| *d == r)
                    .map(|(_, p)| p.clone())
                    .collect();
                proptest::prop_assert_eq!(drain(rx, want.len()), want);
            }
        }
    }

    #[test]
    fn timer_fires_after_its_delay_and_can_be_disarmed() {
        let t = TimerFd::new().expect("timerfd");
        t.set(Some(std::time::Duration::from_millis(5)))
            .expect("arm");
        let start = std::time::Instant::now();
        let mut buf = [0u8; 8];
        loop {
            // SAFETY: reads at most 8 bytes into a live local buffer of 8 bytes.
            let n = unsafe { libc::read(t.as_raw_fd(), buf.as_mut_ptr().cast(), 8) };
            if n == 8 {
                break;
            }
            assert!(
                start.elapsed() < std::time::Duration::from_secs(5),
                "timer never fired"
            );
            std::thread::sleep(std::time::Duration::from_micros(200));
        }
        assert!(start.elapsed() >= std::time::Duration::from_millis(4));
        t.set(None).expect("disarm");
        t.acknowledge();
    }

    #[test]
    fn local_time_is_a_valid_calendar_time() {
        let (y, mo, d, h, mi, s) = local_time(1_723_734_165).expect("convertible");
        assert!((2024..=2024).contains(&y) && (1..=12).contains(&mo) && (1..=31).contains(&d));
        assert!(h < 24 && mi < 60 && s < 61);
    }
}
