"""An independent Zenoh subscriber (the PyPI `eclipse-zenoh` package) that decodes
what it gets with pymavlink: a client of the Zenoh router at ENDPOINT, subscribed to
KEYEXPR. Prints `ready` once subscribed, then one line per sample:

    KEY NAME SOURCE_SYSTEM SOURCE_COMPONENT TARGET_SYSTEM|-

(`bad KEY` for a sample that is not one MAVLink frame). Runs until its stdin closes.

    zenoh_listen.py ENDPOINT KEYEXPR
"""
import sys
import threading

import zenoh
from pymavlink.dialects.v20 import ardupilotmega as mavlink

lock = threading.Lock()


def on_sample(sample):
    key = str(sample.key_expr)
    data = bytes(sample.payload.to_bytes())
    mav = mavlink.MAVLink(None)
    try:
        msgs = mav.parse_buffer(data) or []
    except Exception:
        msgs = []
    with lock:
        if len(msgs) != 1:
            print("bad", key, flush=True)
            return
        m = msgs[0]
        target = getattr(m, "target_system", None)
        print(key, m.get_type(), m.get_srcSystem(), m.get_srcComponent(),
              "-" if target is None else target, flush=True)


conf = zenoh.Config()
conf.insert_json5("mode", '"client"')
conf.insert_json5("connect/endpoints", '["%s"]' % sys.argv[1])
conf.insert_json5("scouting/multicast/enabled", "false")
session = zenoh.open(conf)
sub = session.declare_subscriber(sys.argv[2], on_sample)
print("ready", flush=True)
sys.stdin.read()
sub.undeclare()
session.close()
