"""A simulated vehicle for the end-to-end tests: the autopilot a ground station talks to
through the router (tests/e2e/peers_mavproxy.rs drives MAVProxy against it).

usage:
  vehicle.py LINK [--params N] [--sys S] [--comp C]

LINK, the vehicle's side of its link to the router:
  --serial PATH         makes a pseudo-terminal (raw mode) and points the symlink PATH at
                        its slave end, which the router's `serial` block names
  --udp HOST:PORT       sends to a router's UDP server (and reads what comes back)
  --udp-listen [HOST:]PORT
                        waits for datagrams (a router's UDP client) and answers the
                        address of the last one
  --tcp HOST:PORT       connects to a router's TCP server (reconnects if it goes away)
  --tcp-listen [HOST:]PORT
                        accepts a router's TCP client (one connection at a time; a new
                        one replaces the old)
HOST may be an IPv6 address in brackets, e.g. [::1]:5760. A listener's HOST defaults to
127.0.0.1.

The vehicle is system 1 component 1 (--sys/--comp change that), an ArduPilot quadrotor:
  - HEARTBEAT at 1 Hz (base_mode has the armed flag while armed);
  - N float parameters (default 300) named SIM_P000, SIM_P001, ...;
  - PARAM_REQUEST_LIST: every PARAM_VALUE, with param_index and param_count;
  - PARAM_REQUEST_READ, by index or by name: that PARAM_VALUE;
  - PARAM_SET: stores the value (as a float32) and answers with its PARAM_VALUE;
  - COMMAND_LONG: COMMAND_ACK ACCEPTED to the sender; MAV_CMD_COMPONENT_ARM_DISARM arms
    or disarms;
  - FILE_TRANSFER_PROTOCOL: a NAK (no files here), so that a ground station that tries
    MAVLink FTP for the parameters first (MAVProxy does) falls back to PARAM_REQUEST_LIST
    at once instead of after its FTP time-outs.
Requests addressed to another system or component are ignored.

Standard output, one line per event (the tests wait for these), printed after the
vehicle has sent its answer to it:
  ready                       the link is up (pty made, socket bound or connected, or
                              listening), printed once
  connected ADDR / disconnected
                              a TCP connection came or went
  peer ADDR                   a UDP listener's first datagram from ADDR
  first NAME from S.C         the first message of each type received
  param list from S.C         a PARAM_REQUEST_LIST; "param list sent N" once all are out
  param read NAME             a PARAM_REQUEST_READ (by index or name) of one we have
  param set NAME VALUE        a PARAM_SET, after storing it
  command NNN from S.C        a COMMAND_LONG (NNN is the MAV_CMD number)
  armed / disarmed            after MAV_CMD_COMPONENT_ARM_DISARM
  ftp nak OPCODE              an FTP request answered with a NAK
It stops on end of file on standard input or on SIGTERM, and prints "end" last.
"""
import argparse
import os
import select
import signal
import socket
import struct
import sys
import time
import tty

os.environ["MAVLINK20"] = "1"
from pymavlink.dialects.v20 import ardupilotmega as mavlink  # noqa: E402


def say(line):
    sys.stdout.write(line + "\n")
    sys.stdout.flush()


def split_host_port(where, default_host=None):
    """`HOST:PORT`, `[V6]:PORT`, or (with a default host) `PORT` → (host, port)."""
    if where.startswith("["):
        host, _, port = where[1:].partition("]:")
        return host, int(port)
    if ":" not in where:
        if default_host is None:
            raise SystemExit("%s: HOST:PORT expected" % where)
        return default_host, int(where)
    host, port = where.rsplit(":", 1)
    return host, int(port)


def family_of(host):
    return socket.AF_INET6 if ":" in host else socket.AF_INET


def show(addr):
    host, port = addr[0], addr[1]
    return "[%s]:%d" % (host, port) if ":" in host else "%s:%d" % (host, port)


# Links. Each has fds() (what to wait on), read(fd) (bytes, b"" if nothing) and
# write(data); write drops the data when there is no peer yet.


class Pty:
    def __init__(self, link):
        self.master, self.slave = os.openpty()
        # Raw before anything is written: no echo, no line editing, no CR/LF mangling.
        tty.setraw(self.slave)
        if os.path.lexists(link):
            os.unlink(link)
        os.symlink(os.ttyname(self.slave), link)
        self.link = link

    def fds(self):
        return [self.master]

    def read(self, _fd):
        try:
            return os.read(self.master, 65536)
        except OSError:
            return b""

    def write(self, data):
        # Blocking: the pty's buffer is the back-pressure a real UART would give.
        view = memoryview(data)
        while view:
            n = os.write(self.master, view)
            view = view[n:]

    def close(self):
        try:
            os.unlink(self.link)
        except OSError:
            pass


class UdpOut:
    def __init__(self, where):
        host, port = split_host_port(where)
        self.router = (host, port)
        self.sock = socket.socket(family_of(host), socket.SOCK_DGRAM)
        self.sock.bind(("::1" if ":" in host else "127.0.0.1", 0))

    def fds(self):
        return [self.sock.fileno()]

    def read(self, _fd):
        data, _ = self.sock.recvfrom(65536)
        return data

    def write(self, data):
        try:
            self.sock.sendto(data, self.router)
        except OSError:
            pass  # e.g. ECONNREFUSED from an earlier datagram: UDP goes on

    def close(self):
        self.sock.close()


class UdpListen:
    def __init__(self, where):
        host, port = split_host_port(where, "127.0.0.1")
        self.sock = socket.socket(family_of(host), socket.SOCK_DGRAM)
        self.sock.bind((host, port))
        self.peer = None

    def fds(self):
        return [self.sock.fileno()]

    def read(self, _fd):
        data, addr = self.sock.recvfrom(65536)
        if addr != self.peer:
            self.peer = addr
            say("peer " + show(addr))
        return data

    def write(self, data):
        if self.peer is not None:
            try:
                self.sock.sendto(data, self.peer)
            except OSError:
                pass

    def close(self):
        self.sock.close()


class TcpClient:
    CONNECT_FOR = 10.0

    def __init__(self, where):
        self.host, self.port = split_host_port(where)
        self.sock = None
        self.connect()

    def connect(self):
        # The router's listening socket may be a moment behind its start; retrying for a
        # bounded time keeps that race out of the tests.
        deadline = time.monotonic() + self.CONNECT_FOR
        while True:
            sock = socket.socket(family_of(self.host), socket.SOCK_STREAM)
            try:
                sock.connect((self.host, self.port))
            except OSError as e:
                sock.close()
                if time.monotonic() >= deadline:
                    raise SystemExit("cannot connect to %s:%d: %s" % (self.host, self.port, e))
                time.sleep(0.05)
                continue
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            self.sock = sock
            say("connected " + show(sock.getpeername()))
            return

    def fds(self):
        return [self.sock.fileno()]

    def read(self, _fd):
        try:
            data = self.sock.recv(65536)
        except OSError:
            data = b""
        if not data:
            say("disconnected")
            self.sock.close()
            self.connect()
        return data

    def write(self, data):
        try:
            self.sock.sendall(data)
        except OSError:
            pass  # the read side notices and reconnects

    def close(self):
        self.sock.close()


class TcpListen:
    def __init__(self, where):
        host, port = split_host_port(where, "127.0.0.1")
        self.server = socket.socket(family_of(host), socket.SOCK_STREAM)
        self.server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.server.bind((host, port))
        self.server.listen(4)
        self.conn = None

    def fds(self):
        fds = [self.server.fileno()]
        if self.conn is not None:
            fds.append(self.conn.fileno())
        return fds

    def read(self, fd):
        if fd == self.server.fileno():
            conn, addr = self.server.accept()
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            if self.conn is not None:
                self.conn.close()
            self.conn = conn
            say("connected " + show(addr))
            return b""
        try:
            data = self.conn.recv(65536)
        except OSError:
            data = b""
        if not data:
            say("disconnected")
            self.conn.close()
            self.conn = None
        return data

    def write(self, data):
        if self.conn is not None:
            try:
                self.conn.sendall(data)
            except OSError:
                pass

    def close(self):
        if self.conn is not None:
            self.conn.close()
        self.server.close()


# The vehicle.

FTP_OP_TERMINATE_SESSION = 1
FTP_OP_RESET_SESSIONS = 2
FTP_OP_ACK = 128
FTP_OP_NAK = 129
FTP_ERR_FAIL = 1
FTP_ERR_FILE_NOT_FOUND = 10
FTP_OPEN_OPS = (4, 6, 11)  # OpenFileRO, CreateFile, OpenFileWO


def float32(value):
    return struct.unpack("<f", struct.pack("<f", value))[0]


class Vehicle:
    def __init__(self, link, sysid, compid, count):
        self.link = link
        self.sysid = sysid
        self.compid = compid
        self.mav = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=compid)
        self.mav.robust_parsing = True
        self.names = ["SIM_P%03d" % i for i in range(count)]
        self.values = [float32(1.0 + i * 0.25) for i in range(count)]
        self.index = {name: i for i, name in enumerate(self.names)}
        self.armed = False
        self.seen = set()

    def send(self, msg):
        self.link.write(msg.pack(self.mav))

    def heartbeat(self):
        base_mode = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
        if self.armed:
            base_mode |= mavlink.MAV_MODE_FLAG_SAFETY_ARMED
        state = mavlink.MAV_STATE_ACTIVE if self.armed else mavlink.MAV_STATE_STANDBY
        self.send(mavlink.MAVLink_heartbeat_message(
            mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA,
            base_mode, 0, state, 3))

    def param_value(self, i):
        self.send(mavlink.MAVLink_param_value_message(
            self.names[i].encode(), self.values[i], mavlink.MAV_PARAM_TYPE_REAL32,
            len(self.names), i))

    def for_us(self, msg):
        return (msg.target_system in (0, self.sysid)
                and msg.target_component in (0, self.compid))

    def handle(self, msg):
        kind = msg.get_type()
        if kind == "BAD_DATA":
            return
        src = "%d.%d" % (msg.get_srcSystem(), msg.get_srcComponent())
        if kind not in self.seen:
            self.seen.add(kind)
            say("first %s from %s" % (kind, src))
        handler = getattr(self, "on_" + kind.lower(), None)
        if handler is not None and self.for_us(msg):
            handler(msg, src)

    def on_param_request_list(self, _msg, src):
        say("param list from " + src)
        for i in range(len(self.names)):
            self.param_value(i)
        say("param list sent %d" % len(self.names))

    def on_param_request_read(self, msg, _src):
        if msg.param_index >= 0:
            i = msg.param_index if msg.param_index < len(self.names) else None
        else:
            i = self.index.get(msg.param_id)
        if i is not None:
            self.param_value(i)
            say("param read " + self.names[i])

    def on_param_set(self, msg, _src):
        i = self.index.get(msg.param_id)
        if i is None:
            return
        self.values[i] = float32(msg.param_value)
        self.param_value(i)
        say("param set %s %g" % (self.names[i], self.values[i]))

    def on_command_long(self, msg, src):
        self.send(mavlink.MAVLink_command_ack_message(
            msg.command, mavlink.MAV_RESULT_ACCEPTED, 0, 0,
            msg.get_srcSystem(), msg.get_srcComponent()))
        say("command %d from %s" % (msg.command, src))
        if msg.command == mavlink.MAV_CMD_COMPONENT_ARM_DISARM:
            self.armed = msg.param1 == 1
            self.heartbeat()  # the ground station sees the new state at once
            say("armed" if self.armed else "disarmed")

    def on_file_transfer_protocol(self, msg, _src):
        payload = bytes(msg.payload)
        seq, session, opcode = struct.unpack_from("<HBB", payload)
        if opcode in (FTP_OP_TERMINATE_SESSION, FTP_OP_RESET_SESSIONS):
            reply, data = FTP_OP_ACK, b""
        else:
            error = FTP_ERR_FILE_NOT_FOUND if opcode in FTP_OPEN_OPS else FTP_ERR_FAIL
            reply, data = FTP_OP_NAK, bytes([error])
        # seq, session, opcode, size, req_opcode, burst_complete, padding, offset, data
        out = struct.pack("<HBBBBBBI", (seq + 1) % 65536, session, reply, len(data), opcode,
                          0, 0, 0) + data
        out += bytes(251 - len(out))
        self.send(mavlink.MAVLink_file_transfer_protocol_message(
            0, msg.get_srcSystem(), msg.get_srcComponent(), list(out)))
        if reply == FTP_OP_NAK:
            say("ftp nak %d" % opcode)

    def run(self):
        say("ready")
        next_heartbeat = time.monotonic()
        stdin = sys.stdin.fileno()
        while True:
            now = time.monotonic()
            if now >= next_heartbeat:
                self.heartbeat()
                next_heartbeat += 1.0
                if next_heartbeat < now:
                    next_heartbeat = now + 1.0
            fds = [stdin] + self.link.fds()
            ready, _, _ = select.select(fds, [], [], max(0.0, next_heartbeat - now))
            for fd in ready:
                if fd == stdin:
                    if not os.read(stdin, 4096):
                        return
                    continue
                data = self.link.read(fd)
                if data:
                    for msg in self.mav.parse_buffer(data) or []:
                        self.handle(msg)


def main():
    parser = argparse.ArgumentParser()
    where = parser.add_mutually_exclusive_group(required=True)
    where.add_argument("--serial")
    where.add_argument("--udp")
    where.add_argument("--udp-listen")
    where.add_argument("--tcp")
    where.add_argument("--tcp-listen")
    parser.add_argument("--sys", type=int, default=1)
    parser.add_argument("--comp", type=int, default=1)
    parser.add_argument("--params", type=int, default=300)
    args = parser.parse_args()

    def stop(_signum, _frame):
        raise SystemExit(0)

    signal.signal(signal.SIGTERM, stop)
    if args.serial:
        link = Pty(args.serial)
    elif args.udp:
        link = UdpOut(args.udp)
    elif args.udp_listen:
        link = UdpListen(args.udp_listen)
    elif args.tcp:
        link = TcpClient(args.tcp)
    else:
        link = TcpListen(args.tcp_listen)
    try:
        Vehicle(link, args.sys, args.comp, args.params).run()
    finally:
        link.close()
        say("end")


if __name__ == "__main__":
    main()
