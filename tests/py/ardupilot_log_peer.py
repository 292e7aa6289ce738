"""An ArduPilot-side peer streaming its dataflash log to a router the way ArduPilot's
MAVLink log backend does, for tests/e2e/flight_log_e2e.rs.

usage:
  ardupilot_log_peer.py --udp HOST:PORT --log FILE [--skip S,S,...] [--flights N]
                        [--sys S] [--window W] [--vanish-after B] [--timing]

The peer is system S (default 1) component 1, an ArduPilot (HEARTBEAT.autopilot 3) sending
heartbeats every 100 ms. For each of N flights (default 1) it arms (base_mode has
MAV_MODE_FLAG_SAFETY_ARMED), waits for REMOTE_LOG_BLOCK_STATUS with seqno
MAV_REMOTE_LOG_DATA_BLOCK_START addressed to it, and sends FILE in REMOTE_LOG_DATA_BLOCK
of 200 bytes (the last one zero-padded), numbered from 0, to the address the start came
from, with at most W (default 32) blocks not yet acknowledged. The first sending of each
seqno in --skip is left out: only a NACK (status 0) or the peer's own resend timer
brings it (1 s; ArduPilot's AP_Logger_MAVLink resends after 100 ms, a longer timer here
leaves the gap to the router's NACK). Once every block is ACKed it disarms and waits for the
stop (seqno MAV_REMOTE_LOG_DATA_BLOCK_STOP).

With --vanish-after B the peer goes silent for good (no heartbeat, nothing) once it
has sent B blocks, as when the link drops mid-flight, and prints "vanished".

It prints one line per flight, then "done":
  flight N blocks B acks A nacks K nacked S,S,... resent R stop yes|no
With --timing each flight line is followed by one saying when its first block went and
its last ACK came (time.monotonic(), the system's CLOCK_MONOTONIC, so that a benchmark
can line it up with what it sampled meanwhile: benches/flight_log_stream.py):
  stream N FIRST_SENT LAST_ACKED
"""
import argparse
import os
import sys
import time

os.environ["MAVLINK20"] = "1"
from pymavlink import mavutil  # noqa: E402

START = 2147483646
STOP = 2147483645
BLOCK = 200


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--udp", required=True)
    ap.add_argument("--log", required=True)
    ap.add_argument("--skip", default="")
    ap.add_argument("--flights", type=int, default=1)
    ap.add_argument("--sys", type=int, default=1)
    ap.add_argument("--window", type=int, default=32)
    ap.add_argument("--vanish-after", type=int, default=0)
    ap.add_argument("--timing", action="store_true")
    a = ap.parse_args()
    skip = {int(s) for s in a.skip.split(",") if s}
    data = open(a.log, "rb").read()
    data += bytes(-len(data) % BLOCK)
    blocks = [data[i : i + BLOCK] for i in range(0, len(data), BLOCK)]
    conn = mavutil.mavlink_connection(
        "udpout:" + a.udp, source_system=a.sys, source_component=1, dialect="ardupilotmega"
    )
    state = {"armed": False, "beat": 0.0}

    def beat():
        now = time.monotonic()
        if now - state["beat"] >= 0.1:
            state["beat"] = now
            base = 1 | (128 if state["armed"] else 0)
            conn.mav.heartbeat_send(2, 3, base, 0, 4)

    def statuses(timeout):
        """REMOTE_LOG_BLOCK_STATUS addressed to us within `timeout`."""
        end = time.monotonic() + timeout
        out = []
        while True:
            beat()
            left = end - time.monotonic()
            m = conn.recv_match(type="REMOTE_LOG_BLOCK_STATUS", blocking=True, timeout=max(0.0, min(left, 0.05)))
            if m is not None and m.target_system == a.sys and m.target_component == 1:
                out.append(m)
                continue
            if left <= 0 or out:
                return out

    for flight in range(1, a.flights + 1):
        state["armed"] = True
        client = None
        deadline = time.monotonic() + 20
        while client is None:
            for m in statuses(0.2):
                if m.seqno == START:
                    client = (m.get_srcSystem(), m.get_srcComponent())
            if time.monotonic() > deadline:
                sys.exit("no start request")
        acked = set()
        nacked = []
        sent_at = {}
        acks = nacks = resent = 0
        first_skipped = set()
        nxt = 0
        first_sent = []
        last_acked = 0.0
        deadline = time.monotonic() + 60
        while len(acked) < len(blocks):
            if time.monotonic() > deadline:
                sys.exit("blocks not all acknowledged: %d of %d" % (len(acked), len(blocks)))
            now = time.monotonic()

            def send(s):
                sent_at[s] = time.monotonic()
                if not first_sent:
                    first_sent.append(sent_at[s])
                conn.mav.remote_log_data_block_send(client[0], client[1], s, blocks[s])

            if a.vanish_after and nxt >= a.vanish_after:
                print("vanished", flush=True)
                return
            # sent_at holds the blocks sent (or skipped) and not yet ACKed.
            while nxt < len(blocks) and len(sent_at) < a.window:
                if nxt in skip and nxt not in first_skipped:
                    first_skipped.add(nxt)
                    sent_at[nxt] = now
                else:
                    send(nxt)
                nxt += 1
            for s, t in list(sent_at.items()):
                if now - t > 1.0:
                    send(s)
                    resent += 1
            for m in statuses(0.02):
                if m.seqno >= len(blocks):
                    continue
                if m.status == 1:
                    acks += 1
                    if m.seqno not in acked:
                        last_acked = time.monotonic()
                    acked.add(m.seqno)
                    sent_at.pop(m.seqno, None)
                else:
                    nacks += 1
                    nacked.append(m.seqno)
                    if m.seqno not in acked:
                        send(m.seqno)
                        resent += 1
        state["armed"] = False
        stop = False
        deadline = time.monotonic() + 5
        while not stop and time.monotonic() < deadline:
            stop = any(m.seqno == STOP for m in statuses(0.2))
        print(
            "flight %d blocks %d acks %d nacks %d nacked %s resent %d stop %s"
            % (
                flight,
                len(blocks),
                acks,
                nacks,
                ",".join(str(s) for s in sorted(set(nacked))) or "-",
                resent,
                "yes" if stop else "no",
            ),
            flush=True,
        )
        if a.timing:
            print("stream %d %.6f %.6f" % (flight, first_sent[0], last_acked), flush=True)
        # Disarmed a while between flights.
        end = time.monotonic() + 0.5
        while time.monotonic() < end:
            statuses(0.05)
    print("done", flush=True)


if __name__ == "__main__":
    main()
