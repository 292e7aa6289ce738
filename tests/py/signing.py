"""pymavlink as an independent signer/verifier for the signing tests.

usage: signing.py make            -> prints signed frames (hex, one per line)
       signing.py verify          <- reads hex frames on stdin, prints ok/bad per line
The key is bytes 0..31; link id 3.
"""
import os
import sys

os.environ["MAVLINK20"] = "1"
from pymavlink.dialects.v20 import ardupilotmega as m  # noqa: E402

KEY = bytes(range(32))


def make():
    mav = m.MAVLink(None, srcSystem=42, srcComponent=7)
    mav.signing.secret_key = KEY
    mav.signing.link_id = 3
    mav.signing.timestamp = 0x123456789A
    mav.signing.sign_outgoing = True
    msgs = [
        m.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3),
        m.MAVLink_command_long_message(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0),
        m.MAVLink_param_request_read_message(1, 1, b"SYSID_THISMAV", -1),
        m.MAVLink_statustext_message(6, b"hello from pymavlink"),
        m.MAVLink_ping_message(123456, 7, 0, 0),
        m.MAVLink_set_mode_message(1, 1, 0),
        m.MAVLink_mission_request_list_message(0, 0, 0),
    ]
    for msg in msgs:
        print(msg.pack(mav).hex())


def verify():
    mav = m.MAVLink(None, srcSystem=255, srcComponent=190)
    mav.signing.secret_key = KEY
    mav.signing.sign_outgoing = False
    mav.signing.allow_unsigned_callback = lambda _mav, _msgid: False
    mav.robust_parsing = True
    for line in sys.stdin.read().split():
        try:
            msgs = mav.parse_buffer(bytes.fromhex(line)) or []
        except m.MAVError:
            msgs = []
        ok = len(msgs) == 1 and msgs[0].get_type() != "BAD_DATA" and msgs[0]._signed
        print("ok" if ok else "bad")


{"make": make, "verify": verify}[sys.argv[1]]()
