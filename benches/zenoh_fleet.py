#!/usr/bin/env python3
"""A fleet over Zenoh (issue 21, item 3): N simulated vehicles at 10 Hz spread over edge
routers, one ground-station router, a Zenoh router (the eclipse-zenoh package in router
mode), all on this machine's loopback.

    .venv/bin/python benches/zenoh_fleet.py target/release/mavtables [N ...]

Each edge router has one UDP server; one process per edge sends its vehicles' ATTITUDE
(each vehicle a distinct system id, 10 frames/s, time_boot_ms = the frame's number) to
it. MAVLink system ids are 8 bits, so the fleet is split into prefixes of at most 250
vehicles, one edge router per prefix (`fleet/p0`, `fleet/p1`, ...), and one
ground-station router per prefix (`receive all;`; one router's links share one address
space, so system 1 of two prefixes would be one system to it), each with a UDP server
whose ground station counts what arrives. Per N: 2 s of warm-up, then 10 s measured:

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


def vehicles(prefix, port, systems, count, start_at, sent_q):
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
    sent_q.put((prefix, systems, sent))


def ground_station(ports, stop_at, recv_q, ready):
    """One ground station per ground-station router (`ports`): (prefix, sys, n, t)."""
    import selectors
    sel = selectors.DefaultSelector()
    for k, port in enumerate(ports):
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 24)
        sock.bind(("127.0.0.1", 0))
        sock.setblocking(False)
        mav = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
        sock.sendto(mav.heartbeat_encode(6, 8, 0, 0, 4).pack(mav), ("127.0.0.1", port))
        sel.register(sock, selectors.EVENT_READ, k)
    ready.set()
    got = []
    while time.monotonic() < stop_at:
        for key, _ in sel.select(0.2):
            while True:
                try:
                    data = key.fileobj.recv(4096)
                except BlockingIOError:
                    break
                t = time.monotonic_ns()
                # One frame per datagram: v2 header (10 bytes), ATTITUDE is id 30.
                if len(data) > 14 and data[0] == 0xFD and data[7] == 30:
                    got.append((key.data, data[5], int.from_bytes(data[10:14], "little") - 1, t))
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

    gs_ports, gss = [], []
    for k in range(prefixes):
        port = free_port(socket.SOCK_DGRAM)
        gss.append(router(f"gs{k}", f"udp {{ port {port}; address 127.0.0.1; }}\n"
                          f"zenoh {{ connect {endpoint}; prefix fleet/p{k}; receive all; }}\n"
                          "default_action accept;\n"))
        gs_ports.append(port)
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
    gsp = mp.Process(target=ground_station, args=(gs_ports, stop_at, recv_q, ready))
    gsp.start()
    ready.wait()
    senders = []
    for k, (_, port) in enumerate(edges):
        systems = list(range(1, 1 + min(PER_PREFIX, n - k * PER_PREFIX)))
        s = mp.Process(target=vehicles, args=(k, port, systems, count, start_at, sent_q))
        s.start()
        senders.append((k, s))

    # CPU over the measured window only.
    while time.monotonic() < start_at + WARMUP_S:
        time.sleep(0.01)
    pids = {"zenoh router": zr.pid}
    pids.update({f"gs{k}": p.pid for k, p in enumerate(gss)})
    pids.update({f"edge{k}": p.pid for k, (p, _) in enumerate(edges)})
    cpu0 = {k: cpu_ns(pid) for k, pid in pids.items()}
    while time.monotonic() < start_at + WARMUP_S + MEASURE_S:
        time.sleep(0.01)
    cpu1 = {k: cpu_ns(pid) for k, pid in pids.items()}

    sent = {}
    for _ in senders:
        prefix, systems, times = sent_q.get()
        for s, t in zip(systems, times):
            sent[(prefix, s)] = t
    got = recv_q.get()
    for _, s in senders:
        s.join()
    gsp.join()
    for p in procs:
        p.terminate()
        p.wait()
    zr.stdin.close()
    zr.wait()

    # Latency and loss over the frames sent in the measured window.
    first = int(WARMUP_S * RATE_HZ)
    received = {}
    for prefix, sys_id, num, t in got:
        if num >= first:
            received.setdefault((prefix, sys_id, num), t)
    lat = []
    sent_in_window = len(sent) * (count - first)
    for (prefix, sys_id), times in sent.items():
        for num in range(first, count):
            t = received.get((prefix, sys_id, num))
            if t is not None:
                lat.append((t - times[num]) / 1e6)
    delivered = len(lat)
    lat.sort()
    frames = max(delivered, 1)
    gs_cpu = sum(cpu1[f"gs{k}"] - cpu0[f"gs{k}"] for k in range(prefixes)) / prefixes
    row = {
        "vehicles": n,
        "edges": prefixes,
        "sent/s": sent_in_window / MEASURE_S,
        "delivered/s": delivered / MEASURE_S,
        "loss": (sent_in_window - delivered) / max(sent_in_window, 1),
        "p50 ms": lat[len(lat) // 2] if lat else float("nan"),
        "p99 ms": lat[int(len(lat) * 0.99)] if lat else float("nan"),
        "gs us/frame": gs_cpu / max(1, frames / prefixes) / 1e3,
        "edge us/frame": statistics.mean(
            (cpu1[f"edge{k}"] - cpu0[f"edge{k}"]) / max(1, frames / prefixes) / 1e3
            for k in range(prefixes)),
        "zenohd us/frame": (cpu1["zenoh router"] - cpu0["zenoh router"]) / frames / 1e3,
        "gs cpu %": gs_cpu / MEASURE_S / 1e7,
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
