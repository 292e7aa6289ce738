#!/usr/bin/env python3
"""The training run of profile-guided optimisation (see scripts/pgo and pgo/README.md).

usage: pgo_train.py ROUTER_BINARY

Starts ROUTER_BINARY (a build instrumented with -Cprofile-generate) on a configuration
with the interfaces and rules operators run, sends it the traffic they send, and stops it
with SIGTERM so that it writes its profile. What it exercises is what the optimised
build is laid out for; code it never reaches is compiled as cold (for size). In order:

1. vehicle rates: a ground station (UDP client endpoint) and a vehicle (UDP server)
   that know each other by HEARTBEAT, then targeted COMMAND_LONG frames sent one at a
   time, each only after the one before arrived: one frame per wake-up, the shape of
   traffic at 1k and 10k frames/s, weighted the most;
2. a real flight: tests/data/flight/rural.tlog's frames (48 message types) from the
   vehicle, one datagram each, at full speed: batched receive and send, the parser's
   dialect look-up, broadcast routing;
3. a TCP ground station and a vehicle on a serial port (a pseudo-terminal): stream
   parsing both ways;
4. MAVLink 2 signing: a signed interface whose frames are checked, and signed on the
   way out;
5. the rules: priorities, a rate cap, a reject, a called chain, and recording;
6. a second router with redundant radios (`dedup`, `group`), a paced ground station
   (`max_bitrate`) and a browser-like WebSocket client, fed the flight over both radios.

Every wait is bounded; a phase that does not see its traffic arrive fails the run.
Needs pymavlink (scripts/test installs it into .venv).
"""
import os
import pty
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import termios
import threading
import time
import tty

os.environ.setdefault("MAVLINK20", "1")
from pymavlink.dialects.v20 import common as mavlink  # noqa: E402

VEHICLE, GCS, TCP_GCS, SERIAL_VEHICLE, SIGNED_GCS, WEB_GCS = 1, 255, 254, 2, 250, 240
HERE = os.path.dirname(os.path.abspath(__file__))
FLIGHT = os.path.join(HERE, "..", "tests", "data", "flight", "rural.tlog")
KEY = bytes(range(32))
COMMANDS = 50000
DEADLINE = 60.0


def encoder(system, component=1, key=None):
    mav = mavlink.MAVLink(None, srcSystem=system, srcComponent=component)
    if key is not None:
        mav.signing.secret_key = key
        mav.signing.link_id = 1
        mav.signing.sign_outgoing = True
        mav.signing.timestamp = int((time.time() - 1420070400) * 100000)
    return mav


def pack(mav, msg):
    return msg.pack(mav)


def heartbeat(mav):
    return pack(mav, mav.heartbeat_encode(6, 8, 0, 0, 3))


def command(mav, target, seq):
    return pack(mav, mav.command_long_encode(target, 1, 511, 1, float(seq), 0, 0, 0, 0, 0, 0))


def free_port(kind=socket.SOCK_DGRAM):
    s = socket.socket(socket.AF_INET, kind)
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def flight_frames():
    """The frames of the real flight: each .tlog record is 8 bytes of time, then a frame."""
    with open(FLIGHT, "rb") as f:
        data = f.read()
    frames = []
    i = 0
    while i + 8 < len(data):
        i += 8
        magic = data[i]
        if magic == 0xFD:
            length = 12 + data[i + 1] + (13 if data[i + 2] & 1 else 0)
        elif magic == 0xFE:
            length = 8 + data[i + 1]
        else:
            break
        frames.append(data[i : i + length])
        i += length
    return frames


def expect(sock, want, what):
    """Reads from `sock` until `want(datagram)` holds; fails after DEADLINE seconds."""
    end = time.monotonic() + DEADLINE
    while time.monotonic() < end:
        sock.settimeout(max(0.01, end - time.monotonic()))
        try:
            data = sock.recv(65536)
        except socket.timeout:
            break
        if want(data):
            return data
    raise SystemExit(f"pgo_train: {what} did not arrive within {DEADLINE:.0f} s")


def is_msg(msg_id):
    def check(data):
        return len(data) > 9 and data[0] == 0xFD and data[7:10] == bytes([msg_id & 0xFF, 0, 0])

    return check


class Drain(threading.Thread):
    """Reads a socket until told to stop, counting bytes (so the router never blocks)."""

    def __init__(self, sock):
        super().__init__(daemon=True)
        self.sock, self.bytes, self.stop = sock, 0, False
        sock.settimeout(0.05)

    def run(self):
        while not self.stop:
            try:
                self.bytes += len(self.sock.recv(65536))
            except (socket.timeout, BlockingIOError):
                pass
            except OSError:
                return


def stop(router, log):
    """SIGTERM, then the clean exit that writes the profile."""
    if router.poll() is None:
        router.send_signal(signal.SIGTERM)
        try:
            router.wait(timeout=30)
        except subprocess.TimeoutExpired:
            router.kill()
            raise SystemExit("pgo_train: the router did not stop within 30 s of SIGTERM")
    if router.returncode != 0:
        raise SystemExit(f"pgo_train: the router exited with {router.returncode} (log: {log.name})")


def websocket_client(port):
    """A WebSocket connection to the router, past its handshake (RFC 6455)."""
    ws = socket.create_connection(("127.0.0.1", port), timeout=DEADLINE)
    ws.sendall(
        f"GET /mavlink HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\n"
        "Connection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
        "Sec-WebSocket-Version: 13\r\n\r\n".encode()
    )
    head = b""
    while b"\r\n\r\n" not in head:
        chunk = ws.recv(4096)
        if not chunk:
            raise SystemExit("pgo_train: the WebSocket handshake was refused")
        head += chunk
    if not head.startswith(b"HTTP/1.1 101"):
        raise SystemExit(f"pgo_train: WebSocket handshake answered {head[:40]!r}")
    return ws


def ws_message(frame):
    """`frame` as one masked binary WebSocket message (a client must mask)."""
    mask = os.urandom(4)
    masked = bytes(b ^ mask[i % 4] for i, b in enumerate(frame))
    return bytes([0x82, 0x80 | len(frame)]) + mask + masked


def second_router(router_bin, env, work, frames):
    """Redundant radios, pacing and a WebSocket client (phase 6)."""
    radio_a, radio_b, web_port = free_port(), free_port(), free_port(socket.SOCK_STREAM)
    paced = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    paced.bind(("127.0.0.1", 0))
    conf = os.path.join(work, "radios.conf")
    with open(conf, "w") as f:
        f.write(
            f"""default_action accept;
dedup 500ms;
udp {{ port {radio_a}; address 127.0.0.1; group vehicle; }}
udp {{ port {radio_b}; address 127.0.0.1; group vehicle; }}
udp {{ connect 127.0.0.1:{paced.getsockname()[1]}; max_bitrate 4000000; }}
websocket {{ port {web_port}; address 127.0.0.1; }}
chain default {{
    accept;
}}
"""
        )
    log = open(os.path.join(work, "radios.log"), "w")
    router = subprocess.Popen([router_bin, "--config", conf], stdout=log, stderr=subprocess.STDOUT, env=env)
    try:
        end = time.monotonic() + DEADLINE
        while True:
            try:
                ws = websocket_client(web_port)
                break
            except OSError:
                if time.monotonic() > end or router.poll() is not None:
                    raise SystemExit(f"pgo_train: no WebSocket server (log: {log.name})")
                time.sleep(0.05)
        web = encoder(WEB_GCS)
        ws.sendall(ws_message(heartbeat(web)))
        radio = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        drains = [Drain(ws), Drain(paced)]
        for d in drains:
            d.start()
        # A quarter of the flight: these features run here, most routers have none of
        # them, and the counts say how often each branch is taken.
        for i, frame in enumerate(frames[::4]):
            radio.sendto(frame, ("127.0.0.1", radio_a))
            radio.sendto(frame, ("127.0.0.1", radio_b))
            if i % 16 == 0:
                ws.sendall(ws_message(command(web, VEHICLE, i)))
        # The paced ground station gets the last frames (4 Mbit/s) before the stop.
        time.sleep(3.0)
        if drains[0].bytes == 0 or drains[1].bytes == 0:
            raise SystemExit("pgo_train: the WebSocket or the paced station received nothing")
        for d in drains:
            d.stop = True
    finally:
        stop(router, log)
    log.close()


def main():
    if len(sys.argv) != 2:
        raise SystemExit(__doc__)
    router_bin = sys.argv[1]
    work = tempfile.mkdtemp(prefix="mavtables-pgo-")
    udp_port, tcp_port, signed_port = free_port(), free_port(socket.SOCK_STREAM), free_port()
    gcs = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    gcs.bind(("127.0.0.1", 0))
    vehicle = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    vehicle.bind(("127.0.0.1", 0))
    signed_gcs = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    signed_gcs.bind(("127.0.0.1", 0))
    master, slave = pty.openpty()
    tty.setraw(master)
    tty.setraw(slave)
    attrs = termios.tcgetattr(slave)
    attrs[4] = attrs[5] = termios.B115200
    termios.tcsetattr(slave, termios.TCSANOW, attrs)
    key_path = os.path.join(work, "key")
    with open(key_path, "w") as f:
        f.write(KEY.hex())
    os.chmod(key_path, 0o600)
    conf = os.path.join(work, "router.conf")
    with open(conf, "w") as f:
        f.write(
            f"""default_action accept;
udp {{ port {udp_port}; address 127.0.0.1; }}
udp {{ connect 127.0.0.1:{gcs.getsockname()[1]}; }}
tcp {{ port {tcp_port}; address 127.0.0.1; }}
serial {{ device {os.ttyname(slave)}; baudrate 115200; }}
udp {{ port {signed_port}; address 127.0.0.1; signing_key {key_path}; allow_unsigned yes; }}
record {{ path {work}/rec-%Y%m%d-%H%M%S.tlog; max_file_bytes 20000000; max_files 2; }}
chain default {{
    reject if ENCAPSULATED_DATA;
    accept with priority 10 if COMMAND_LONG;
    accept with rate 20/s if ATTITUDE to {TCP_GCS}.0/8;
    call telemetry if from {VEHICLE}.0/8;
    accept;
}}
chain telemetry {{
    accept with priority 5 if HEARTBEAT;
    accept with priority 1 if GLOBAL_POSITION_INT;
}}
"""
        )
    env = dict(os.environ, LLVM_PROFILE_FILE=os.environ.get("LLVM_PROFILE_FILE", "default_%p.profraw"))
    log = open(os.path.join(work, "router.log"), "w")
    router = subprocess.Popen([router_bin, "--config", conf], stdout=log, stderr=subprocess.STDOUT, env=env)
    to_router = ("127.0.0.1", udp_port)
    try:
        v, g = encoder(VEHICLE), encoder(GCS)
        # 1. vehicle rates: the router learns both ends, then one frame per wake-up.
        end = time.monotonic() + DEADLINE
        while True:
            if time.monotonic() > end or router.poll() is not None:
                raise SystemExit(f"pgo_train: the router did not forward a HEARTBEAT (log: {log.name})")
            vehicle.sendto(heartbeat(v), to_router)
            gcs.settimeout(0.2)
            try:
                data, peer = gcs.recvfrom(65536)
            except socket.timeout:
                continue
            if is_msg(0)(data):
                break
        gcs.sendto(heartbeat(g), peer)
        expect(vehicle, is_msg(0), "the ground station's HEARTBEAT at the vehicle")
        for seq in range(COMMANDS):
            vehicle.sendto(command(v, GCS, seq), to_router)
            expect(gcs, is_msg(76), "a COMMAND_LONG at the ground station")
            if seq % 2 == 0:
                gcs.sendto(command(g, VEHICLE, seq), peer)
                expect(vehicle, is_msg(76), "a COMMAND_LONG at the vehicle")
        # 3. streams: a TCP ground station and a serial vehicle join.
        tcp = socket.create_connection(("127.0.0.1", tcp_port), timeout=DEADLINE)
        t = encoder(TCP_GCS)
        tcp.sendall(heartbeat(t))
        serial_vehicle = encoder(SERIAL_VEHICLE)
        os.write(master, heartbeat(serial_vehicle))
        expect(gcs, lambda d: is_msg(0)(d) and d[5] == TCP_GCS, "the TCP station's HEARTBEAT")
        tcp_drain = Drain(tcp)
        tcp_drain.start()
        # 4. a signed ground station joins.
        s = encoder(SIGNED_GCS, key=KEY)
        signed_gcs.sendto(heartbeat(s), ("127.0.0.1", signed_port))
        expect(gcs, lambda d: is_msg(0)(d) and d[5] == SIGNED_GCS, "the signed station's HEARTBEAT")
        drains = [Drain(gcs), Drain(signed_gcs)]
        for d in drains:
            d.start()
        # 2. the real flight, at full speed, with the other peers talking meanwhile.
        frames = flight_frames()
        serial_out = threading.Thread(target=serial_echo, args=(master,), daemon=True)
        serial_out.start()
        for rounds in range(3):
            for i, frame in enumerate(frames):
                vehicle.sendto(frame, to_router)
                if i % 64 == 0:
                    tcp.sendall(command(t, VEHICLE, i))
                    os.write(master, command(serial_vehicle, GCS, i))
                    signed_gcs.sendto(command(s, VEHICLE, i), ("127.0.0.1", signed_port))
                    gcs.sendto(heartbeat(g), peer)
        # The last frames reach the ends before the router stops.
        time.sleep(1.0)
        if tcp_drain.bytes == 0 or drains[1].bytes == 0:
            raise SystemExit("pgo_train: the TCP or the signed station received nothing")
        for d in drains + [tcp_drain]:
            d.stop = True
    finally:
        stop(router, log)
    log.close()
    second_router(router_bin, env, work, frames)
    shutil.rmtree(work)
    print(f"pgo_train: {COMMANDS} commands one at a time, 3 × {len(frames)} flight frames, TCP, serial, signing; radios, pacing, WebSocket")


def serial_echo(master):
    """Reads what the router writes to the serial vehicle (so its writes never block)."""
    while True:
        try:
            if not os.read(master, 65536):
                return
        except OSError:
            return


if __name__ == "__main__":
    main()
