#!/usr/bin/env python3
"""User-space instructions per forwarded frame, counted by valgrind's callgrind.

usage: instructions_per_frame.py mavtables|mavlink-router BINARY [N1 N2]

Starts the router under `valgrind --tool=callgrind` with a UDP server (where the
generator sends) and a UDP client endpoint of a sink, every frame accepted (the same
set-up as `cargo bench --bench versus_router`), makes the sink known with HEARTBEATs,
then sends N targeted COMMAND_LONG frames one at a time, each only after the one
before reached the sink (one frame per wake-up, as at the rates vehicles send). The
count for N1 frames is taken from the count for N2 frames; start-up and shutdown cancel
out, so (I(N2) - I(N1)) / (N2 - N1) is what one more frame costs. Instruction counts do
not depend on the machine's load, so this figure can be compared across builds on a
busy machine where CPU time cannot.

Needs valgrind and pymavlink (`.venv/bin/python` after scripts/test).
"""
import os
import re
import signal
import socket
import subprocess
import sys
import tempfile
import time

os.environ.setdefault("MAVLINK20", "1")
from pymavlink.dialects.v20 import common as mavlink  # noqa: E402

GEN_SYSTEM, SINK_SYSTEM = 1, 101


def frame(system, build):
    mav = mavlink.MAVLink(None, srcSystem=system, srcComponent=1)
    return build(mav).pack(mav)


def heartbeat(system):
    return frame(system, lambda m: m.heartbeat_encode(6, 8, 0, 0, 3))


def command(seq):
    return frame(
        GEN_SYSTEM,
        lambda m: m.command_long_encode(SINK_SYSTEM, 1, 511, 1, float(seq), 0, 0, 0, 0, 0, 0),
    )


def start(kind, binary, port, sink_port, workdir, out):
    valgrind = ["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}"]
    if kind == "mavtables":
        conf = os.path.join(workdir, "router.conf")
        with open(conf, "w") as f:
            f.write(
                f"udp {{\n    port {port};\n    address 127.0.0.1;\n}}\n"
                f"udp {{\n    connect 127.0.0.1:{sink_port};\n}}\n"
                "default_action accept;\nchain default {\n    accept;\n}\n"
            )
        args = [binary, "--config", conf]
    else:
        conf = os.path.join(workdir, "main.conf")
        with open(conf, "w") as f:
            f.write("[General]\nTcpServerPort = 0\n")
        args = [binary, "-c", conf, "-t", "0", "-e", f"127.0.0.1:{sink_port}", f"127.0.0.1:{port}"]
    log = open(os.path.join(workdir, "router.log"), "w")
    return subprocess.Popen(valgrind + args, stdout=log, stderr=subprocess.STDOUT)


def count(kind, binary, n):
    with tempfile.TemporaryDirectory(prefix="ipf-") as workdir:
        sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sender.bind(("127.0.0.1", 0))
        sink = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sink.bind(("127.0.0.1", 0))
        sink.settimeout(0.2)
        probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
        probe.close()
        out = os.path.join(workdir, "callgrind.out")
        router = start(kind, binary, port, sink.getsockname()[1], workdir, out)
        try:
            deadline = time.monotonic() + 60
            answered = False
            while True:
                if time.monotonic() > deadline:
                    raise SystemExit(f"{kind}: nothing reached the sink within 60 s")
                sender.sendto(command(0) if answered else heartbeat(GEN_SYSTEM), ("127.0.0.1", port))
                try:
                    data, peer = sink.recvfrom(4096)
                except socket.timeout:
                    continue
                if answered and data[7:10] == bytes([76, 0, 0]):
                    break
                sink.sendto(heartbeat(SINK_SYSTEM), peer)
                answered = True
            time.sleep(0.3)
            sink.settimeout(0.05)
            try:
                while True:
                    sink.recvfrom(4096)
            except socket.timeout:
                pass
            sink.settimeout(10)
            for seq in range(1, n + 1):
                sender.sendto(command(seq), ("127.0.0.1", port))
                while True:
                    data, _ = sink.recvfrom(4096)
                    if data[7:10] == bytes([76, 0, 0]):
                        break
        finally:
            router.send_signal(signal.SIGTERM)
            router.wait(timeout=60)
        with open(out) as f:
            text = f.read()
        m = re.search(r"^(?:summary|totals): (\d+)", text, re.M)
        if not m:
            raise SystemExit(f"{kind}: no totals in {out}")
        return int(m.group(1))


def main():
    if len(sys.argv) not in (3, 5):
        raise SystemExit(__doc__)
    kind, binary = sys.argv[1], sys.argv[2]
    if kind not in ("mavtables", "mavlink-router"):
        raise SystemExit(__doc__)
    n1, n2 = (int(sys.argv[3]), int(sys.argv[4])) if len(sys.argv) == 5 else (1000, 3000)
    i1 = count(kind, binary, n1)
    i2 = count(kind, binary, n2)
    per = (i2 - i1) / (n2 - n1)
    print(f"{kind}: {i1} instructions for {n1} frames, {i2} for {n2}: {per:.0f} per frame")


if __name__ == "__main__":
    main()
