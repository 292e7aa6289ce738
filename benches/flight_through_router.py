#!/usr/bin/env python3
"""Router CPU per frame on real traffic: the recorded flight through the router.

Usage (after `cargo build --release` and `scripts/test`, which makes `.venv`):

    .venv/bin/python benches/flight_through_router.py [ROUNDS] [ROUTER ...]

For each router binary (default: target/release/mavtables), interleaved over ROUNDS
rounds (default 5): start it on a free port of 127.0.0.1 with one UDP interface that
accepts everything, let one listener (255.190) announce itself with a HEARTBEAT, replay
tests/data/flight/rural.tlog (33,261 frames of 48 message types) at full speed with
`mavtables replay --speed max` ten times, and read the router's user + system CPU time
from /proc/<pid>/stat. Prints, per router, the median over rounds of CPU per received
frame and how many frames reached the listener (the frames addressed to other systems
are not forwarded to it, so about 64% arrive).
"""

import os
import socket
import statistics
import subprocess
import sys
import tempfile
import time

from pymavlink.dialects.v20 import ardupilotmega as mavlink

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
FLIGHT = os.path.join(ROOT, "tests/data/flight/rural.tlog")
FLIGHT_FRAMES = 33261
REPLAYS = 10
TICKS = os.sysconf("SC_CLK_TCK")


def cpu_seconds(pid):
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICKS


def free_port():
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def one_round(router, replayer):
    port = free_port()
    with tempfile.TemporaryDirectory() as tmp:
        conf = os.path.join(tmp, "router.conf")
        with open(conf, "w") as f:
            f.write(f"udp {{ port {port}; address 127.0.0.1; }}\n"
                    "default_action accept;\nchain default { accept; }\n")
        proc = subprocess.Popen([router, "--config", conf],
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            listener = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            listener.bind(("127.0.0.1", 0))
            # Room for a whole flight's worth (64 MiB) so the listener never drops: beyond
            # net.core.rmem_max with SO_RCVBUFFORCE (33) where allowed (root).
            try:
                listener.setsockopt(socket.SOL_SOCKET, 33, 64 << 20)
            except PermissionError:
                listener.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 64 << 20)
            gcs = mavlink.MAVLink(None, 255, 190)
            hb = gcs.heartbeat_encode(6, 8, 0, 0, 4).pack(gcs)
            time.sleep(0.3)  # the router binds its port
            if proc.poll() is not None:
                raise RuntimeError(f"{router} exited")
            listener.sendto(hb, ("127.0.0.1", port))
            time.sleep(0.2)  # and learns the listener
            before = cpu_seconds(proc.pid)
            got = 0
            for _ in range(REPLAYS):
                subprocess.run([replayer, "replay", FLIGHT, "--to", f"udp:127.0.0.1:{port}",
                                "--speed", "max"],
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)
                listener.settimeout(0.3)
                try:
                    while True:
                        listener.recv(4096)
                        got += 1
                except socket.timeout:
                    pass
            cpu = cpu_seconds(proc.pid) - before
        finally:
            proc.terminate()
            proc.wait()
    frames = FLIGHT_FRAMES * REPLAYS
    return cpu * 1e6 / frames, got, frames


def main():
    rounds = int(sys.argv[1]) if len(sys.argv) > 1 else 5
    default = os.path.join(ROOT, "target/release/mavtables")
    routers = sys.argv[2:] or [default]
    replayer = default
    results = {r: [] for r in routers}
    for _ in range(rounds):
        for r in routers:
            us, got, frames = one_round(r, replayer)
            results[r].append(us)
            print(f"  {r}: {us:.2f} us/frame, {got}/{frames} frames reached the listener")
    for r, v in results.items():
        print(f"{r}: median {statistics.median(v):.2f} us of router CPU per received frame "
              f"over {rounds} rounds of {REPLAYS} flights")


if __name__ == "__main__":
    main()
