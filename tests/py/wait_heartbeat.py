"""A peer that stays silent until it hears a HEARTBEAT, as PX4 on USB does
(tests/e2e/redundant_links.rs).

usage: wait_heartbeat.py PORT [TIMEOUT]

Listens on 127.0.0.1:PORT with pymavlink (MAVLink 2), waits up to TIMEOUT seconds
(default 10) for two heartbeats, and prints for each one line
"SYS COMP TYPE AUTOPILOT BASE_MODE CUSTOM_MODE STATUS VERSION SEQ MAVLINK2"; exits 1 if
none came.
"""
import os
import sys

os.environ["MAVLINK20"] = "1"
from pymavlink import mavutil  # noqa: E402

port = int(sys.argv[1])
timeout = float(sys.argv[2]) if len(sys.argv) > 2 else 10.0
conn = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}", source_system=255)
got = 0
for _ in range(2):
    m = conn.wait_heartbeat(timeout=timeout)
    if m is None:
        break
    h = m.get_header()
    v2 = 1 if m.get_msgbuf()[0] == 0xFD else 0
    print(m.get_srcSystem(), m.get_srcComponent(), m.type, m.autopilot, m.base_mode,
          m.custom_mode, m.system_status, m.mavlink_version, h.seq, v2, flush=True)
    got += 1
sys.exit(0 if got else 1)
