"""A pymavlink peer that signs and checks MAVLink 2 signatures, for the signing tests
(tests/e2e/signing_peers.rs). It is independent of the router: pymavlink's own signing
(`mav.signing`) signs what it sends and checks what it receives, and every signed frame
received is also checked here explicitly with hashlib, so a frame the router signed is
verified by code that shares nothing with it.

usage:
  signing_peer.py LINK --sys S --comp C [--key HEX] [--sign] [--link-id N]
                  [--timestamp T] [--require-signed] [--vehicle]

LINK is `--udp HOST:PORT` (sends to a router's UDP server) or `--tcp HOST:PORT`
(connects to a router's TCP server, retrying for up to 10 s).

--key HEX           the 32-byte key (64 hex digits): received signed frames are checked
                    with it, and with --sign every frame sent is signed with it
--link-id N         the link id of the frames it signs (default 0)
--timestamp T       the first signing timestamp (10 us units since 2015-01-01; default now)
--require-signed    unsigned frames (and frames whose signature fails) are rejected by
                    pymavlink (its allow_unsigned_callback says no); otherwise they are
                    taken as unsigned
--vehicle           answers a COMMAND_LONG addressed to it (or broadcast) with a
                    COMMAND_ACK ACCEPTED to the sender

Standard output, one line per event:
  ready                          the link is up
  sent HEX                       a frame it sent, as sent
  recv NAME from S.C signed=0|1 link=L ts=T check=ok|bad|none HEX
                                 a message pymavlink accepted; signed is pymavlink's
                                 verdict (msg._signed), link and ts are from the
                                 signature block (-1 if none), check is the explicit
                                 hashlib check of the signature with --key (none: the
                                 frame has no signature block, or there is no key)
  rejected REASON... HEX         a frame pymavlink refused (BAD_DATA)
  acked CMD to S.C               (--vehicle) a COMMAND_ACK went out
  stats sig=N good=N bad=N unsigned=N reject=N
                                 pymavlink's signing counters (on "stats" and at the end)
  end                            last line
Commands on standard input, one per line:
  heartbeat [TYPE]               a HEARTBEAT (MAV_TYPE number, default 6 = GCS)
  command S.C CMD                a COMMAND_LONG to S.C (MAV_CMD number)
  text WORDS...                  a STATUSTEXT
  stats                          prints the stats line
End of input stops it.
"""
import argparse
import hashlib
import os
import select
import socket
import struct
import sys
import time

os.environ["MAVLINK20"] = "1"
from pymavlink.dialects.v20 import ardupilotmega as mavlink  # noqa: E402

EPOCH_2015 = 1420070400


def say(line):
    sys.stdout.write(line + "\n")
    sys.stdout.flush()


def now_timestamp():
    return int((time.time() - EPOCH_2015) * 100000)


class Udp:
    def __init__(self, where):
        host, port = where.rsplit(":", 1)
        self.router = (host, int(port))
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4 << 20)
        self.sock.bind(("127.0.0.1", 0))

    def fileno(self):
        return self.sock.fileno()

    def read(self):
        data, _ = self.sock.recvfrom(65536)
        return data

    def write(self, data):
        self.sock.sendto(data, self.router)


class Tcp:
    def __init__(self, where):
        host, port = where.rsplit(":", 1)
        deadline = time.monotonic() + 10.0
        while True:
            sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            try:
                sock.connect((host, int(port)))
                break
            except OSError as e:
                sock.close()
                if time.monotonic() >= deadline:
                    raise SystemExit("cannot connect to %s: %s" % (where, e))
                time.sleep(0.05)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.sock = sock

    def fileno(self):
        return self.sock.fileno()

    def read(self):
        try:
            return self.sock.recv(65536)
        except OSError:
            return b""

    def write(self, data):
        self.sock.sendall(data)


def explicit_check(key, buf):
    """The signature of a signed MAVLink 2 frame, checked with hashlib alone."""
    if key is None or len(buf) < 13 or buf[0] != 0xFD or not (buf[2] & 1):
        return "none"
    expected = hashlib.sha256(key + bytes(buf[:-6])).digest()[:6]
    return "ok" if expected == bytes(buf[-6:]) else "bad"


class Peer:
    def __init__(self, link, args):
        self.link = link
        self.key = bytes.fromhex(args.key) if args.key else None
        self.vehicle = args.vehicle
        self.mav = mavlink.MAVLink(None, srcSystem=args.sys, srcComponent=args.comp)
        self.mav.robust_parsing = True
        if self.key is not None:
            s = self.mav.signing
            s.secret_key = self.key
            s.sign_outgoing = args.sign
            s.link_id = args.link_id
            s.timestamp = args.timestamp if args.timestamp is not None else now_timestamp()
            allow = not args.require_signed
            s.allow_unsigned_callback = lambda _mav, _msgid: allow

    def send(self, msg):
        data = msg.pack(self.mav)
        self.link.write(data)
        say("sent " + data.hex())

    def stats(self):
        s = self.mav.signing
        say("stats sig=%d good=%d bad=%d unsigned=%d reject=%d" % (
            s.sig_count, s.goodsig_count, s.badsig_count, s.unsigned_count, s.reject_count))

    def command(self, words):
        if not words:
            return
        if words[0] == "heartbeat":
            kind = int(words[1]) if len(words) > 1 else mavlink.MAV_TYPE_GCS
            self.send(mavlink.MAVLink_heartbeat_message(
                kind, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, mavlink.MAV_STATE_ACTIVE, 3))
        elif words[0] == "command":
            s, c = (int(x) for x in words[1].split("."))
            self.send(mavlink.MAVLink_command_long_message(
                s, c, int(words[2]), 0, 1, 0, 0, 0, 0, 0, 0))
        elif words[0] == "text":
            self.send(mavlink.MAVLink_statustext_message(
                mavlink.MAV_SEVERITY_INFO, " ".join(words[1:]).encode()))
        elif words[0] == "stats":
            self.stats()
        else:
            raise SystemExit("unknown command %r" % words)

    def received(self, msg):
        if msg.get_type() == "BAD_DATA":
            say("rejected %s %s" % (msg.reason, bytes(msg.data).hex()))
            return
        buf = bytes(msg.get_msgbuf())
        signed = len(buf) > 12 and buf[0] == 0xFD and (buf[2] & 1)
        link = buf[-13] if signed else -1
        ts = int.from_bytes(buf[-12:-6], "little") if signed else -1
        say("recv %s from %d.%d signed=%d link=%d ts=%d check=%s %s" % (
            msg.get_type(), msg.get_srcSystem(), msg.get_srcComponent(),
            1 if msg.get_signed() else 0, link, ts, explicit_check(self.key, buf), buf.hex()))
        if (self.vehicle and msg.get_type() == "COMMAND_LONG"
                and msg.target_system in (0, self.mav.srcSystem)
                and msg.target_component in (0, self.mav.srcComponent)):
            self.send(mavlink.MAVLink_command_ack_message(
                msg.command, mavlink.MAV_RESULT_ACCEPTED, 0, 0,
                msg.get_srcSystem(), msg.get_srcComponent()))
            say("acked %d to %d.%d" % (msg.command, msg.get_srcSystem(), msg.get_srcComponent()))

    def run(self):
        say("ready")
        stdin = sys.stdin.fileno()
        pending = b""
        while True:
            ready, _, _ = select.select([stdin, self.link.fileno()], [], [])
            if self.link.fileno() in ready:
                data = self.link.read()
                if not data:
                    say("disconnected")
                    return
                for msg in self.mav.parse_buffer(data) or []:
                    self.received(msg)
            if stdin in ready:
                chunk = os.read(stdin, 4096)
                if not chunk:
                    return
                pending += chunk
                while b"\n" in pending:
                    line, pending = pending.split(b"\n", 1)
                    self.command(line.decode().split())


def main():
    parser = argparse.ArgumentParser()
    where = parser.add_mutually_exclusive_group(required=True)
    where.add_argument("--udp")
    where.add_argument("--tcp")
    parser.add_argument("--sys", type=int, required=True)
    parser.add_argument("--comp", type=int, required=True)
    parser.add_argument("--key")
    parser.add_argument("--sign", action="store_true")
    parser.add_argument("--link-id", type=int, default=0)
    parser.add_argument("--timestamp", type=int)
    parser.add_argument("--require-signed", action="store_true")
    parser.add_argument("--vehicle", action="store_true")
    args = parser.parse_args()
    link = Udp(args.udp) if args.udp else Tcp(args.tcp)
    peer = Peer(link, args)
    try:
        peer.run()
    finally:
        peer.stats()
        say("end")


if __name__ == "__main__":
    main()
