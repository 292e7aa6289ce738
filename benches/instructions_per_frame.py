#!/usr/bin/env python3
"""User-space instructions per forwarded frame, counted by valgrind's callgrind.

usage: instructions_per_frame.py [--cache | --footprint] mavtables|mavlink-router BINARY [N1 N2]

Starts the router under `valgrind --tool=callgrind` with a UDP server (where the
generator sends) and a UDP client endpoint of a sink, every frame accepted (the same
set-up as `cargo bench --bench versus_router`), makes the sink known with HEARTBEATs,
then sends N targeted COMMAND_LONG frames one at a time, each only after the one
before reached the sink (one frame per wake-up, as at the rates vehicles send). The
count for N1 frames is taken from the count for N2 frames; start-up and shutdown cancel
out, so (I(N2) - I(N1)) / (N2 - N1) is what one more frame costs. Instruction counts do
not depend on the machine's load, so this figure can be compared across builds on a
busy machine where CPU time cannot.

With --cache, callgrind also simulates first-level caches of 8 KiB (2-way, 64-byte
lines) and prints the instruction and data lines missed per frame: how much code and
data one frame touches. A wake-up finds little of the router in the real first-level
caches (the kernel's receive, send and scheduling paths ran in between), so these lines
come from farther away at every frame, and their number, not the instruction count,
sets most of the router's user-space time at the rates vehicles send.

With --footprint, valgrind's lackey traces every instruction and memory access of N2
frames instead, and the script prints what one frame touches, whatever the cache: the
distinct code and data lines (64 bytes) and pages (4 KiB) between one frame's wake-up
and the next (medians over the frames of the middle of the run). A frame is told from
the next by an instruction that runs once a frame: of the instructions run more than
50 times, the most common count is the number of frames, and one of the instructions
with that count marks where each frame's trace starts.

Needs valgrind and pymavlink (`.venv/bin/python` after scripts/test).
"""
import itertools
import os
import re
import signal
import socket
import statistics
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


CACHE = ["--cache-sim=yes", "--I1=8192,2,64", "--D1=8192,2,64", "--LL=1048576,16,64"]


def start(kind, binary, port, sink_port, workdir, out, cache):
    if cache == "footprint":
        valgrind = ["valgrind", "--tool=lackey", "--trace-mem=yes", f"--log-file={out}"]
    else:
        valgrind = ["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}"]
    if cache is True:
        valgrind += CACHE
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


def count(kind, binary, n, cache):
    """Runs the router under callgrind for `n` frames; returns its totals."""
    return run(kind, binary, n, cache, totals)


def totals(kind, out):
    with open(out) as f:
        text = f.read()
    events = re.search(r"^events: (.*)$", text, re.M)
    found = re.search(r"^(?:summary|totals): (.*)$", text, re.M)
    if not events or not found:
        raise SystemExit(f"{kind}: no totals in {out}")
    return dict(zip(events.group(1).split(), map(int, found.group(1).split())))


def footprint(kind, out):
    """Medians, per frame, of the distinct lines and pages of code and data that one
    frame touches (see --footprint above), from lackey's trace in `out`."""
    def accesses():
        with open(out) as f:
            for line in f:
                if len(line) > 3 and line[0] in " I" and "," in line:
                    yield line[0] == "I", int(line[3:].split(",", 1)[0], 16)

    # The middle of the run: the frames, past start-up and before shutdown.
    total = sum(1 for _ in accesses())
    window = list(itertools.islice(accesses(), total // 2, total * 19 // 20))
    per_addr = {}
    for code, addr in window:
        if code:
            per_addr[addr] = per_addr.get(addr, 0) + 1
    counts = {}
    for c in per_addr.values():
        if c > 50:
            counts[c] = counts.get(c, 0) + 1
    if not counts:
        raise SystemExit(f"{kind}: no frames in the trace {out}")
    frames = max(counts, key=counts.get)
    marker = next(a for a, c in per_addr.items() if c == frames)
    rows = []
    current = None
    for code, addr in window:
        if code and addr == marker:
            if current is not None:
                rows.append([len(x) if isinstance(x, set) else x for x in current])
            current = [set(), set(), set(), set(), 0, 0]
        if current is None:
            continue
        base = 0 if code else 1
        current[base].add(addr >> 6)
        current[base + 2].add(addr >> 12)
        current[4 + base] += 1
    if len(rows) < 10:
        raise SystemExit(f"{kind}: only {len(rows)} frames found in the trace {out}")
    return [statistics.median(r[i] for r in rows) for i in range(6)] + [len(rows)]


def run(kind, binary, n, cache, read):
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
        router = start(kind, binary, port, sink.getsockname()[1], workdir, out, cache)
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
        return read(kind, out)


def main():
    args = sys.argv[1:]
    cache = "--cache" in args
    traced = "--footprint" in args
    args = [a for a in args if a not in ("--cache", "--footprint")]
    if len(args) not in (2, 4) or (cache and traced):
        raise SystemExit(__doc__)
    kind, binary = args[0], args[1]
    if kind not in ("mavtables", "mavlink-router"):
        raise SystemExit(__doc__)
    n1, n2 = (int(args[2]), int(args[3])) if len(args) == 4 else (1000, 3000)
    if traced:
        code_lines, data_lines, code_pages, data_pages, instrs, accesses, frames = run(
            kind, binary, n2, "footprint", footprint
        )
        print(
            f"{kind}: one frame (median of {frames}) runs {instrs:.0f} instructions and"
            f" {accesses:.0f} data accesses, touching {code_lines:.0f} code lines and"
            f" {data_lines:.0f} data lines (64 bytes), {code_pages:.0f} code pages and"
            f" {data_pages:.0f} data pages (4 KiB)"
        )
        return
    c1 = count(kind, binary, n1, cache)
    c2 = count(kind, binary, n2, cache)
    per = {k: (c2[k] - c1.get(k, 0)) / (n2 - n1) for k in c2}
    i1, i2 = c1["Ir"], c2["Ir"]
    print(f"{kind}: {i1} instructions for {n1} frames, {i2} for {n2}: {per['Ir']:.0f} per frame")
    if cache:
        data = per["D1mr"] + per["D1mw"]
        print(
            f"{kind}: per frame, {per['I1mr']:.0f} instruction lines and {data:.0f} data lines"
            " missed in 8 KiB first-level caches"
        )


if __name__ == "__main__":
    main()
