"""pymavlink as an independent MAVLink peer of the running router (tests/router_e2e.rs).

usage:
  peer.py dialect
      prints "v1|v2 ID NAME CRC_EXTRA PAYLOAD_SIZE" for every message pymavlink can build
  peer.py send   LINK --sys S --comp C [--v1] [--heartbeat] [--gap SEC] ITEM...
  peer.py listen LINK --sys S --comp C [--no-heartbeat] [--count N] [--timeout SEC]
                 [--linger SEC]

LINK is `--udp HOST:PORT` (the router's socket) or `--serial PATH`: the peer makes a
pseudo-terminal itself (raw mode) and points the symlink PATH at its slave end, which is
what the router's config names. ITEM is `NAME` or `NAME@S.C` (a target address; without
one every target field is 0, i.e. broadcast).

Protocol on stdout/stdin, one line each: after setting the link up the peer prints
"setup" and waits for a line on stdin (the test's "go"). Then
  send:   prints "sent HEX" for each frame as it goes, then "done";
  listen: sends one HEARTBEAT (unless --no-heartbeat), prints "ready", then one line
          "NAME from S.C HEX" per message received; after --count messages it keeps
          listening --linger seconds (to catch extras), and it stops anyway after
          --timeout seconds. Prints "end" last.
"""
import argparse
import atexit
import os
import select
import signal
import socket
import sys
import time
import tty

os.environ["MAVLINK20"] = "1"
from pymavlink.dialects.v10 import ardupilotmega as v1  # noqa: E402
from pymavlink.dialects.v20 import ardupilotmega as v2  # noqa: E402

TARGET_FIELDS = ("target_system", "target", "target_component")


def say(line):
    sys.stdout.write(line + "\n")
    sys.stdout.flush()


class Udp:
    def __init__(self, where):
        host, port = where.rsplit(":", 1)
        self.router = (host, int(port))
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4 << 20)
        self.sock.bind(("127.0.0.1", 0))

    def write(self, data):
        self.sock.sendto(data, self.router)

    def read(self, timeout):
        ready, _, _ = select.select([self.sock], [], [], max(timeout, 0))
        if not ready:
            return b""
        data, _ = self.sock.recvfrom(65536)
        return data


class Pty:
    def __init__(self, link):
        self.master, self.slave = os.openpty()
        # Raw before anything is written: no echo, no line editing, no CR/LF mangling.
        tty.setraw(self.slave)
        if os.path.lexists(link):
            os.unlink(link)
        os.symlink(os.ttyname(self.slave), link)
        # The link goes before the pty does: once this process exits the kernel may hand
        # the same /dev/pts number to another test's pty, and a router still retrying this
        # path would open that one instead.
        atexit.register(Pty.unlink, link, os.ttyname(self.slave))
        signal.signal(signal.SIGTERM, lambda *_: sys.exit(0))

    @staticmethod
    def unlink(link, target):
        try:
            if os.readlink(link) == target:
                os.unlink(link)
        except OSError:
            pass

    def write(self, data):
        view = memoryview(data)
        while view:
            n = os.write(self.master, view)
            view = view[n:]

    def read(self, timeout):
        ready, _, _ = select.select([self.master], [], [], max(timeout, 0))
        if not ready:
            return b""
        try:
            return os.read(self.master, 65536)
        except OSError:
            return b""


def value(ftype, length, seed):
    """A deterministic, mostly non-zero value of a field."""
    def one(k):
        if ftype in ("float", "double"):
            return (k % 97) * 0.5 + 1.25
        if ftype == "char":
            return b"A"
        bits = int("".join(c for c in ftype if c.isdigit()))
        span = 1 << bits
        v = (k * 2654435761 + 12345) % span or 1
        if ftype.startswith("int"):
            v -= span // 2
        return v

    if ftype == "char":
        text = "mavtables%03d" % (seed % 1000)
        return text[: length or 1].encode()
    if length:
        return [one(seed + i) for i in range(length)]
    return one(seed)


def build(module, name, target, seed):
    cls = module.mavlink_map[getattr(module, "MAVLINK_MSG_ID_" + name)]
    lengths = dict(zip(cls.ordered_fieldnames, cls.array_lengths))
    types = dict(zip(cls.fieldnames, cls.fieldtypes))
    args = []
    for i, field in enumerate(cls.fieldnames):
        if field in TARGET_FIELDS:
            s, c = target
            args.append(c if field == "target_component" else s)
        else:
            args.append(value(types[field], lengths.get(field, 0), seed * 31 + i))
    return cls(*args)


def parse_item(item):
    if "@" in item:
        name, addr = item.split("@")
        s, c = addr.split(".")
        return name, (int(s), int(c))
    return item, (0, 0)


def link_of(args):
    return Udp(args.udp) if args.udp else Pty(args.serial)


def wait_for_go():
    say("setup")
    if not sys.stdin.readline():
        sys.exit(0)


def cmd_dialect(_args):
    for version, module in (("v1", v1), ("v2", v2)):
        for msg_id, cls in sorted(module.mavlink_map.items()):
            say("%s %d %s %d %d" % (version, msg_id, cls.msgname, cls.crc_extra, cls.unpacker.size))


def cmd_send(args):
    link = link_of(args)
    module = v1 if args.v1 else v2
    mav = module.MAVLink(None, srcSystem=args.sys, srcComponent=args.comp)
    wait_for_go()
    items = list(args.items)
    if args.heartbeat:
        items.insert(0, "HEARTBEAT")
    for seed, item in enumerate(items):
        name, target = parse_item(item)
        frame = build(module, name, target, seed).pack(mav)
        link.write(frame)
        say("sent " + frame.hex())
        if args.gap:
            time.sleep(args.gap)
    say("done")


def describe(msg):
    return "%s from %d.%d %s" % (
        msg.get_type(),
        msg.get_srcSystem(),
        msg.get_srcComponent(),
        bytes(msg.get_msgbuf()).hex(),
    )


def cmd_listen(args):
    link = link_of(args)
    mav = v2.MAVLink(None, srcSystem=args.sys, srcComponent=args.comp)
    mav.robust_parsing = True
    wait_for_go()
    if not args.no_heartbeat:
        link.write(v2.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3).pack(mav))
    say("ready")
    start = time.monotonic()
    deadline = start + args.timeout
    received = 0
    while True:
        now = time.monotonic()
        if now >= deadline:
            break
        data = link.read(deadline - now)
        if not data:
            continue
        for msg in mav.parse_buffer(data) or []:
            if msg.get_type() == "BAD_DATA":
                say("BAD_DATA " + bytes(msg.get_msgbuf()).hex())
                continue
            say(describe(msg))
            received += 1
            if args.count is not None and received == args.count:
                deadline = min(deadline, time.monotonic() + args.linger)
    say("end")


def main():
    parser = argparse.ArgumentParser()
    sub = parser.add_subparsers(dest="cmd", required=True)
    sub.add_parser("dialect")
    for name in ("send", "listen"):
        p = sub.add_parser(name)
        where = p.add_mutually_exclusive_group(required=True)
        where.add_argument("--udp")
        where.add_argument("--serial")
        p.add_argument("--sys", type=int, required=True)
        p.add_argument("--comp", type=int, required=True)
        if name == "send":
            p.add_argument("--v1", action="store_true")
            p.add_argument("--heartbeat", action="store_true")
            p.add_argument("--gap", type=float, default=0.0003)
            p.add_argument("items", nargs="*")
        else:
            p.add_argument("--no-heartbeat", action="store_true")
            p.add_argument("--count", type=int)
            p.add_argument("--timeout", type=float, default=10.0)
            p.add_argument("--linger", type=float, default=0.3)
    args = parser.parse_args()
    {"dialect": cmd_dialect, "send": cmd_send, "listen": cmd_listen}[args.cmd](args)


if __name__ == "__main__":
    main()
