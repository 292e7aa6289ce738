#!/usr/bin/env python3
"""A flight log streamed through the router while it forwards telemetry at full rate.

Usage (after `cargo build --release` and `scripts/test`, which makes `.venv`):

    .venv/bin/python benches/flight_log_stream.py [ROUNDS] [--records N] [--window W]

Each round (default 3), in a temp dir: makes a dataflash log of N ATT records (default
20000: 460,887 bytes, 2,305 blocks) with tests/py/dataflash_log.py; starts the release
router with one UDP interface on 127.0.0.1, a `flight_log { system 2; }` block and a
`stats` block; lets a ground station (255.190) announce itself; then, at the same time,
replays tests/data/flight/rural.tlog (33,261 frames; its vehicle is system 1, a PX4
whose heartbeats arm and disarm: the logging vehicle must be another system) with
`mavtables replay --speed max` over and over as full-rate telemetry, and runs
tests/py/ardupilot_log_peer.py as the ArduPilot of system 2 streaming the log with at
most W (default 64) blocks unacknowledged. The replayed frames are kept from the
logging vehicle by a rule (`reject if to 2.0/8;`): a real autopilot is not sent another
vehicle's telemetry, and the Python peer would spend its time parsing it. The router's
/stats is sampled every 100 ms meanwhile.

Each round also streams the log once without the telemetry (interleaved), for the ratio.
Prints per round, and the medians over rounds: the log's blocks/s and KB/s (from the
peer's first block sent to its last block ACKed), the frames/s the router took in and
forwarded to the ground station meanwhile (from the router's /stats snapshots, taken
once a second, around that span),
whether the written .bin equals the source (zero-padded to whole blocks) byte for byte,
the flight log's lost / dropped / resent counts, the links' queue drops, the UDP
datagrams the kernel dropped meanwhile for a full receive buffer (/proc/net/snmp
RcvbufErrors: the whole machine's, the ground station's socket included) and the
router's CPU time over the whole round (start, log, the 2 s until the file is closed).

Not run by `cargo test` (a script, not a bench target): one round takes about 10 s.
Exits non-zero if a written log differs from the source or lost or dropped blocks.
"""

import argparse
import json
import os
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request

from pymavlink.dialects.v20 import ardupilotmega as mavlink

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
FLIGHT = os.path.join(ROOT, "tests/data/flight/rural.tlog")
PY = os.path.join(ROOT, ".venv/bin/python")
ROUTER = os.path.join(ROOT, "target/release/mavtables")
BLOCK = 200
LOG_SYSTEM = 2


TICKS = os.sysconf("SC_CLK_TCK")


def cpu_seconds(pid):
    """User + system CPU time of process `pid` so far."""
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICKS


def udp_rcvbuf_errors():
    """Datagrams the kernel dropped for a full receive buffer, on the whole machine."""
    with open("/proc/net/snmp") as f:
        rows = [line.split() for line in f if line.startswith("Udp:")]
    return int(rows[1][rows[0].index("RcvbufErrors")])


def free_port(kind):
    with socket.socket(socket.AF_INET, kind) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def stats(http):
    with urllib.request.urlopen(f"http://127.0.0.1:{http}/stats", timeout=5) as r:
        return json.load(r)


def wait_stats(http, proc):
    end = time.monotonic() + 10
    while time.monotonic() < end:
        if proc.poll() is not None:
            raise RuntimeError("the router exited")
        try:
            return stats(http)
        except OSError:
            time.sleep(0.05)
    raise RuntimeError("/stats never answered")


def gcs_out(s, gcs_port):
    """Frames the router sent to the ground station's link."""
    name = f"127.0.0.1:{gcs_port}"
    return sum(link["frames_out"] for link in s["links"] if link["name"] == name)


def frames_in(s):
    return sum(i["frames"] for i in s["interfaces"])


def rates(samples, t0, t1):
    """Frames/s in and to the ground station over the /stats snapshots around [t0, t1].

    /stats is a snapshot the router takes once a second (`uptime_s` says when), so the
    rates are taken between the last snapshot at or before t0 and the first at or after
    t1: a span of the log's length plus up to 2 s, over which the telemetry runs
    without a pause.
    """
    # The router's start on the monotonic clock: a snapshot is never newer than the
    # moment it is read.
    epoch = min(at - s[0] for at, s in samples)
    snaps = sorted({s[0]: s for _, s in samples}.values())
    a = [x for x in snaps if epoch + x[0] <= t0] or snaps[:1]
    b = [x for x in snaps if epoch + x[0] >= t1] or snaps[-1:]
    a, b = a[-1], b[0]
    span = b[0] - a[0]
    return (b[1] - a[1]) / span, (b[2] - a[2]) / span, span


def one_round(records, window, telemetry):
    port = free_port(socket.SOCK_DGRAM)
    http = free_port(socket.SOCK_STREAM)
    with tempfile.TemporaryDirectory() as tmp:
        source = os.path.join(tmp, "source.bin")
        subprocess.run([PY, os.path.join(ROOT, "tests/py/dataflash_log.py"), "make", source,
                        "--records", str(records)], check=True, stdout=subprocess.DEVNULL)
        data = open(source, "rb").read()
        padded = data + bytes(-len(data) % BLOCK)
        blocks = len(padded) // BLOCK
        logs = os.path.join(tmp, "logs")
        conf = os.path.join(tmp, "router.conf")
        with open(conf, "w") as f:
            f.write(
                f"udp {{ port {port}; address 127.0.0.1; }}\n"
                f"flight_log {{ system {LOG_SYSTEM}; path {logs}/flight-%Y%m%d-%H%M%S; "
                "min_free_bytes 0; }\n"
                f"stats {{ address 127.0.0.1; port {http}; }}\n"
                f"chain default {{ reject if to {LOG_SYSTEM}.0/8; accept; }}\n"
                "default_action accept;\n")
        err = open(os.path.join(tmp, "router.err"), "w+")
        proc = subprocess.Popen([ROUTER, "--config", conf],
                                stdout=subprocess.DEVNULL, stderr=err)
        stop = threading.Event()
        stop_sampling = threading.Event()
        samples = []
        try:
            wait_stats(http, proc)
            gcs = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            gcs.bind(("127.0.0.1", 0))
            gcs_port = gcs.getsockname()[1]
            try:
                gcs.setsockopt(socket.SOL_SOCKET, 33, 64 << 20)  # SO_RCVBUFFORCE (root)
            except PermissionError:
                gcs.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 64 << 20)
            me = mavlink.MAVLink(None, 255, 190)
            gcs.sendto(me.heartbeat_encode(6, 8, 0, 0, 4).pack(me), ("127.0.0.1", port))
            got = [0]

            def drain():
                gcs.settimeout(0.2)
                while not stop.is_set():
                    try:
                        gcs.recv(4096)
                        got[0] += 1
                    except socket.timeout:
                        pass

            replays = [0]

            def replay():
                while not stop.is_set():
                    subprocess.run([ROUTER, "replay", FLIGHT, "--to", f"udp:127.0.0.1:{port}",
                                    "--speed", "max"], stdout=subprocess.DEVNULL,
                                   stderr=subprocess.DEVNULL, check=True)
                    replays[0] += 1

            def sample():
                while not stop_sampling.is_set():
                    s = stats(http)
                    snap = (s["uptime_s"], frames_in(s), gcs_out(s, gcs_port))
                    samples.append((time.monotonic(), snap))
                    time.sleep(0.1)

            overflows = udp_rcvbuf_errors()
            threads = [threading.Thread(target=f, daemon=True) for f in (drain, sample)]
            for t in threads:
                t.start()
            time.sleep(0.3)  # the router learns the ground station
            replayer = threading.Thread(target=replay, daemon=True)
            if telemetry:
                replayer.start()
                time.sleep(0.5)  # the telemetry is at full rate before the log begins
            peer = subprocess.run(
                [PY, os.path.join(ROOT, "tests/py/ardupilot_log_peer.py"), "--udp",
                 f"127.0.0.1:{port}", "--log", source, "--sys", str(LOG_SYSTEM), "--window",
                 str(window), "--timing"], capture_output=True, text=True, check=True)
            stop.set()
            if telemetry:
                replayer.join()
            overflows = udp_rcvbuf_errors() - overflows
            # The log is closed 2 s after the disarm.
            end = time.monotonic() + 10
            while time.monotonic() < end:
                s = stats(http)
                if s["flight_log"]["streaming"] is None and \
                        s["flight_log"]["blocks_written"] >= blocks:
                    break
                time.sleep(0.1)
            final = stats(http)
            cpu = cpu_seconds(proc.pid)
            stop_sampling.set()
            for t in threads:
                t.join()
        finally:
            stop.set()
            stop_sampling.set()
            proc.terminate()
            proc.wait()
        flight = next(line for line in peer.stdout.splitlines() if line.startswith("flight "))
        stream = next(line for line in peer.stdout.splitlines() if line.startswith("stream "))
        t0, t1 = (float(x) for x in stream.split()[2:4])
        seconds = t1 - t0
        in_fps, gcs_fps, span = rates(samples, t0, t1)
        written = sorted(os.listdir(logs)) if os.path.isdir(logs) else []
        bins = [w for w in written if w.endswith(".bin")]
        same = len(bins) == 1 and open(os.path.join(logs, bins[0]), "rb").read() == padded
        f = final["flight_log"]
        queue_drops = sum(link["drops"]["queue_full"] for link in final["links"])
        return {
            "blocks_s": blocks / seconds,
            "kb_s": len(padded) / seconds / 1000,
            "in_fps": in_fps,
            "gcs_fps": gcs_fps,
            "span": span,
            "cpu": cpu,
            "overflows": overflows,
            "seconds": seconds,
            "blocks": blocks,
            "bytes": len(padded),
            "same": same,
            "files": len(bins),
            "lost": f["lost"],
            "dropped": f["dropped_queue_full"] + f["dropped_disk"],
            "resent": f["resent"],
            "nacks": f["nacks"],
            "duplicates": f["duplicates"],
            "queue_drops": queue_drops,
            "replays": replays[0],
            "gcs_got": got[0],
            "peer": flight,
        }


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("rounds", type=int, nargs="?", default=3)
    ap.add_argument("--records", type=int, default=20000)
    ap.add_argument("--window", type=int, default=64)
    a = ap.parse_args()
    if not os.path.exists(ROUTER):
        sys.exit("no target/release/mavtables: run cargo build --release first")
    print(f"load average before: {os.getloadavg()[0]:.2f}")
    results = {True: [], False: []}
    for n in range(a.rounds):
        for telemetry in (True, False):
            r = one_round(a.records, a.window, telemetry)
            results[telemetry].append(r)
            print(f"round {n + 1} {'with' if telemetry else 'without'} telemetry: "
                  f"{r['blocks']} blocks ({r['bytes']} bytes) in {r['seconds']:.2f} s: "
                  f"{r['blocks_s']:.0f} blocks/s, {r['kb_s']:.1f} KB/s; meanwhile the router "
                  f"took in {r['in_fps']:.0f} frames/s and sent the ground station "
                  f"{r['gcs_fps']:.0f}/s (over {r['span']:.0f} s of snapshots; {r['replays']} replays done, {r['gcs_got']} frames "
                  f"read); written .bin {'equals' if r['same'] else 'DIFFERS FROM'} the source "
                  f"({r['files']} files); lost {r['lost']}, dropped {r['dropped']}, "
                  f"NACKs {r['nacks']}, resent {r['resent']}, duplicates {r['duplicates']}, "
                  f"queue drops {r['queue_drops']}; UDP datagrams dropped by the kernel for a "
                  f"full receive buffer (anywhere on the machine) {r['overflows']}; router CPU {r['cpu']:.2f} s in all; "
                  f"peer: {r['peer']}", flush=True)
    med = {}
    for telemetry, rs in results.items():
        m = {k: statistics.median(r[k] for r in rs)
             for k in ("blocks_s", "kb_s", "in_fps", "gcs_fps", "seconds", "cpu")}
        med[telemetry] = m
        print(f"median over {a.rounds} rounds {'with' if telemetry else 'without'} telemetry: "
              f"{m['blocks_s']:.0f} blocks/s ({m['kb_s']:.1f} KB/s, {m['seconds']:.2f} s), "
              f"router in {m['in_fps']:.0f} frames/s, to the ground station "
              f"{m['gcs_fps']:.0f} frames/s, router CPU {m['cpu']:.2f} s; byte for byte: {sum(r['same'] for r in rs)}/"
              f"{a.rounds}; lost {sum(r['lost'] for r in rs)}, dropped "
              f"{sum(r['dropped'] for r in rs)}, queue drops {sum(r['queue_drops'] for r in rs)}")
    print(f"log rate with telemetry / without: "
          f"{med[True]['blocks_s'] / med[False]['blocks_s']:.2f}")
    print(f"load average after: {os.getloadavg()[0]:.2f}")
    if not all(r["same"] and r["lost"] == 0 and r["dropped"] == 0
               for rs in results.values() for r in rs):
        sys.exit(1)


if __name__ == "__main__":
    main()
