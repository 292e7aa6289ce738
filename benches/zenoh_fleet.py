#!/usr/bin/env python3
"""A fleet over Zenoh (issue 21, item 3): N simulated vehicles at 10 Hz spread over edge
routers, one ground-station router, a Zenoh router (the eclipse-zenoh package in router
mode), all on this machine's loopback.

    .venv/bin/python benches/zenoh_fleet.py target/release/mavtables [N ...]

Each edge router has one UDP server; one process per edge sends its vehicles' ATTITUDE
(each vehicle a distinct system id, 10 frames/s, time_boot_ms = the frame's number) to
it. MAVLink system ids are 8 bits, so the fleet is split into prefixes of at most 250
vehicles, one edge router per prefix (`fleet/p0`, `fleet/p1`, ...); the ground-station
router has one `zenoh` block per prefix (`receive all;`) and a UDP server whose ground
station counts what arrives. Per N: 2 s of warm-up, then 10 s measured:

  delivered   frames/s at the ground station, and loss (sent - delivered) / sent
  latency     p50 / p99 from the vehicle's send to the ground station's receive
  cpu/frame   each router's CPU time (all its threads, Zenoh's too, from
              /proc/PID/task/*/schedstat) per frame it carried, and the Zenoh router's

The routers and the Zenoh router are started afresh for every N.
"""
import glob
import multiprocessing as mp
import os
import socket
import statistics
import subprocess
import sys
import tempfile
import time

from pymavlink.dialects.v20 import common as mavlink

HERE = os.path.dirname(os.path.abspath(__file__))
ZENOH_ROUTER = os.path.join(HERE, "..", "tests", "py", "zenoh_router.py")
RATE_HZ = 10
WARMUP_S = 2.0
MEASURE_S = 10.0
PER_PREFIX = 250


def free_port(kind):
    s = socket.socket(socket.AF_INET, kind)
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def cpu_ns(pid):
    total = 0
    for path in glob.glob(f"/proc/{pid}/task/*/schedstat"):
        try:
            with open(path) as f:
                total += int(f.read().split()[0])
        except OSError:
            pass
    return total


def frames_for(systems, count):
    """Every frame each of `systems` sends, by number: frames[i][n]."""
    out = []
    for system in systems:
        mav = mavlink.MAVLink(None, srcSystem=system, srcComponent=1)
        out.append([
            mav.attitude_encode(n + 1, 0.1, 0.2, 0.3, 0.01, 0.02, 0.03).pack(mav)
            for n in range(count)
        ])
    return out


def vehicles(port, systems, count, start_at, sent_q):
    """Sends `count` frames per system at 10 Hz each, spread evenly; returns send times."""
    frames = frames_for(systems, count)
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 16)
    sent = [[0] * count for _ in systems]
    step = 1.0 / (RATE_HZ * len(systems))
    while time.monotonic() < start_at:
        time.sleep(0.001)
    t0 = time.monotonic()
    k = 0
    for n in range(count):
        for i in range(len(systems)):
            due = t0 + k * step
            k += 1
            delay = due - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            sent[i][n] = time.monotonic_ns()
            sock.sendto(frames[i][n], ("127.0.0.1", port))
    sent_q.put((systems, sent))


def ground_station(port, stop_at, recv_q, ready):
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 24)
    sock.bind(("127.0.0.1", 0))
    mav = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    sock.sendto(mav.heartbeat_encode(6, 8, 0, 0, 4).pack(mav), ("127.0.0.1", port))
    ready.set()
    sock.settimeout(0.2)
    got = []  # (prefix index unknown here: the edge's port decides) (sys, n, t)
    while time.monotonic() < stop_at:
        try:
            data = sock.recv(4096)
        except socket.timeout:
            continue
        t = time.monotonic_ns()
        # One frame per datagram: v2 header (10 bytes), ATTITUDE is id 30.
        if len(data) > 14 and data[0] == 0xFD and data[7] == 30:
            got.append((data[5], int.from_bytes(data[10:14], "little") - 1, t))
    recv_q.put(got)


def run(exe, n):
    prefixes = (n + PER_PREFIX - 1) // PER_PREFIX
    tmp = tempfile.mkdtemp(prefix="zenoh-fleet-")
    zport = free_port(socket.SOCK_STREAM)
    endpoint = f"tcp/127.0.0.1:{zport}"
    zr = subprocess.Popen([sys.executable, ZENOH_ROUTER, endpoint], stdin=subprocess.PIPE,
                          stdout=subprocess.PIPE, text=True)
    assert zr.stdout.readline().strip() == "ready"
    procs = []

    def router(name, config):
        path = os.path.join(tmp, name + ".conf")
        with open(path, "w") as f:
            f.write(config)
        p = subprocess.Popen([exe, "--config", path, "--loglevel", "0"],
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        procs.append(p)
        return p

    gs_port = free_port(socket.SOCK_DGRAM)
    blocks = "".join(
        f"zenoh {{ connect {endpoint}; prefix fleet/p{k}; receive all; }}\n" for k in range(prefixes))
    gs = router("gs", f"udp {{ port {gs_port}; address 127.0.0.1; }}\n{blocks}default_action accept;\n")
    edges = []
    for k in range(prefixes):
        port = free_port(socket.SOCK_DGRAM)
        p = router(f"edge{k}", f"udp {{ port {port}; address 127.0.0.1; }}\n"
                   f"zenoh {{ connect {endpoint}; prefix fleet/p{k}; }}\ndefault_action accept;\n")
        edges.append((p, port))
    time.sleep(1.0)  # the sessions connect (no traffic is measured before the warm-up)

    count = int((WARMUP_S + MEASURE_S) * RATE_HZ)
    start_at = time.monotonic() + 1.0
    stop_at = start_at + WARMUP_S + MEASURE_S + 2.0
    sent_q, recv_q, ready = mp.Queue(), mp.Queue(), mp.Event()
    gsp = mp.Process(target=ground_station, args=(gs_port, stop_at, recv_q, ready))
    gsp.start()
    ready.wait()
    senders = []
    for k, (_, port) in enumerate(edges):
        systems = list(range(1, 1 + min(PER_PREFIX, n - k * PER_PREFIX)))
        s = mp.Process(target=vehicles, args=(port, systems, count, start_at, sent_q))
        s.start()
        senders.append((k, s))

    # CPU over the measured window only.
    while time.monotonic() < start_at + WARMUP_S:
        time.sleep(0.01)
    pids = {"gs": gs.pid, "zenoh router": zr.pid}
    pids.update({f"edge{k}": p.pid for k, (p, _) in enumerate(edges)})
    cpu0 = {k: cpu_ns(pid) for k, pid in pids.items()}
    while time.monotonic() < start_at + WARMUP_S + MEASURE_S:
        time.sleep(0.01)
    cpu1 = {k: cpu_ns(pid) for k, pid in pids.items()}

    sent = {}
    for k, _ in senders:
        systems, times = sent_q.get()
        for s, t in zip(systems, times):
            sent.setdefault(s, []).append(t)
    got = recv_q.get()
    for _, s in senders:
        s.join()
    gsp.join()
    for p in procs:
        p.terminate()
        p.wait()
    zr.stdin.close()
    zr.wait()

    # Latency and loss over the frames sent in the measured window. With several
    # prefixes the same system id exists once per prefix: frames are matched by
    # (system, number) against the sends of every prefix with that system, earliest
    # unmatched first (the ids of different prefixes send at different phases).
    first = int(WARMUP_S * RATE_HZ)
    window = set(range(first, count))
    received = {}
    for sys_id, num, t in got:
        if num in window:
            received.setdefault((sys_id, num), []).append(t)
    lat, sent_in_window, delivered = [], 0, 0
    for sys_id, lists in sent.items():
        for num in window:
            sends = sorted(times[num] for times in lists)
            sent_in_window += len(sends)
            recvs = sorted(received.get((sys_id, num), []))
            delivered += min(len(sends), len(recvs))
            for s_t, r_t in zip(sends, recvs):
                lat.append((r_t - s_t) / 1e6)
    lat.sort()
    frames = max(delivered, 1)
    row = {
        "vehicles": n,
        "edges": prefixes,
        "sent/s": sent_in_window / MEASURE_S,
        "delivered/s": delivered / MEASURE_S,
        "loss": (sent_in_window - delivered) / max(sent_in_window, 1),
        "p50 ms": lat[len(lat) // 2] if lat else float("nan"),
        "p99 ms": lat[int(len(lat) * 0.99)] if lat else float("nan"),
        "gs us/frame": (cpu1["gs"] - cpu0["gs"]) / frames / 1e3,
        "edge us/frame": statistics.mean(
            (cpu1[f"edge{k}"] - cpu0[f"edge{k}"]) / max(1, frames / prefixes) / 1e3
            for k in range(prefixes)),
        "zenohd us/frame": (cpu1["zenoh router"] - cpu0["zenoh router"]) / frames / 1e3,
        "gs cpu %": (cpu1["gs"] - cpu0["gs"]) / MEASURE_S / 1e7,
        "edge cpu %": statistics.mean(
            (cpu1[f"edge{k}"] - cpu0[f"edge{k}"]) for k in range(prefixes)) / MEASURE_S / 1e7,
        "zenohd cpu %": (cpu1["zenoh router"] - cpu0["zenoh router"]) / MEASURE_S / 1e7,
    }
    return row


def main():
    exe = sys.argv[1]
    sizes = [int(a) for a in sys.argv[2:]] or [10, 100, 1000]
    rows = [run(exe, n) for n in sizes]
    keys = list(rows[0].keys())
    print("| " + " | ".join(keys) + " |")
    print("|" + "---|" * len(keys))
    for r in rows:
        print("| " + " | ".join(
            f"{r[k]:.3g}" if isinstance(r[k], float) else str(r[k]) for k in keys) + " |")


if __name__ == "__main__":
    main()
