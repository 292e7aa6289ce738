"""A PX4-side peer streaming its ulog to a router the way PX4's logger does over
MAVLink, for tests/e2e/flight_log_e2e.rs.

usage:
  px4_log_peer.py --udp HOST:PORT --log FILE --defs N [--skip S,S,...]
                  [--skip-acked S,S,...]

The peer is system 1 component 1, a PX4 (HEARTBEAT.autopilot 12) sending heartbeats
every 100 ms. It arms, waits for COMMAND_LONG MAV_CMD_LOGGING_START addressed to it
(answered with COMMAND_ACK), then sends FILE in chunks of at most 249 bytes numbered
from 0, each with first_message_offset (where its first ulog message starts, 255 if
none): the first N bytes (the header and definitions) in LOGGING_DATA_ACKED, one at a
time, each sent again after 0.3 s until a LOGGING_ACK of its sequence comes (the first
sending of each --skip-acked sequence is left out); the rest in LOGGING_DATA, leaving
out the chunks numbered in --skip (lost for good: PX4 does not resend them). Then it
disarms and waits for MAV_CMD_LOGGING_STOP.

It prints "chunks C acked A resent R lost L stop yes|no", then "done".
"""
import argparse
import os
import struct
import sys
import time

os.environ["MAVLINK20"] = "1"
from pymavlink import mavutil  # noqa: E402

CHUNK = 249
START, STOP = 2510, 2511


def message_starts(data):
    starts = set()
    at = 16
    while at + 3 <= len(data):
        starts.add(at)
        (size,) = struct.unpack_from("<H", data, at)
        at += 3 + size
    return starts


def chunks(data, defs):
    starts = message_starts(data)
    out = []
    for lo, hi in ((0, defs), (defs, len(data))):
        for at in range(lo, hi, CHUNK):
            end = min(at + CHUNK, hi)
            first = next((s - at for s in range(at, end) if s in starts), 255)
            out.append((data[at:end], first, at < defs))
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--udp", required=True)
    ap.add_argument("--log", required=True)
    ap.add_argument("--defs", type=int, required=True)
    ap.add_argument("--skip", default="")
    ap.add_argument("--skip-acked", default="")
    a = ap.parse_args()
    skip = {int(s) for s in a.skip.split(",") if s}
    skip_acked = {int(s) for s in a.skip_acked.split(",") if s}
    data = open(a.log, "rb").read()
    parts = chunks(data, a.defs)
    conn = mavutil.mavlink_connection(
        "udpout:" + a.udp, source_system=1, source_component=1, dialect="ardupilotmega"
    )
    state = {"armed": True, "beat": 0.0}

    def beat():
        now = time.monotonic()
        if now - state["beat"] >= 0.1:
            state["beat"] = now
            base = 1 | (128 if state["armed"] else 0)
            conn.mav.heartbeat_send(2, 12, base, 0, 4)

    def recv(types, timeout):
        end = time.monotonic() + timeout
        while True:
            beat()
            left = end - time.monotonic()
            if left <= 0:
                return None
            m = conn.recv_match(type=types, blocking=True, timeout=min(left, 0.05))
            if m is not None and m.target_system == 1 and m.target_component == 1:
                return m

    def wait_command(command, timeout):
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            m = recv(["COMMAND_LONG"], 0.2)
            if m is not None and m.command == command:
                conn.mav.command_ack_send(command, 0, 0, 0, m.get_srcSystem(), m.get_srcComponent())
                return (m.get_srcSystem(), m.get_srcComponent())
        return None

    client = wait_command(START, 20)
    if client is None:
        sys.exit("no start command")
    acked = resent = lost = 0
    for seq, (body, first, reliable) in enumerate(parts):
        padded = body + bytes(CHUNK - len(body))
        if reliable:
            first_send = seq not in skip_acked
            for attempt in range(20):
                if attempt > 0 or first_send:
                    conn.mav.logging_data_acked_send(
                        client[0], client[1], seq, len(body), first, padded
                    )
                if attempt > 0:
                    resent += 1
                end = time.monotonic() + 0.3
                got = False
                while time.monotonic() < end:
                    m = recv(["LOGGING_ACK"], end - time.monotonic())
                    if m is not None and m.sequence == seq:
                        got = True
                        break
                if got:
                    acked += 1
                    break
            else:
                sys.exit("chunk %d never acknowledged" % seq)
        elif seq in skip:
            lost += 1
        else:
            conn.mav.logging_data_send(client[0], client[1], seq, len(body), first, padded)
            if seq % 16 == 0:
                beat()
                time.sleep(0.002)
    state["armed"] = False
    stopped = wait_command(STOP, 5) is not None
    print(
        "chunks %d acked %d resent %d lost %d stop %s"
        % (len(parts), acked, resent, lost, "yes" if stopped else "no"),
        flush=True,
    )
    print("done", flush=True)


if __name__ == "__main__":
    main()
