"""Parses frames given as hex lines on stdin with pymavlink (the ardupilotmega dialect,
no signing key), one datagram per line, and prints per message it finds:
`TYPE LENGTH` (TYPE as pymavlink names it: `UNKNOWN_<id>` for an id its dialect lacks,
whose checksum it cannot check; `BAD_DATA` for a frame it refuses, a bad checksum
included), LENGTH the bytes of the frame it framed (signature included). The independent reader of what
mavtables forwarded."""

import os
import sys

os.environ["MAVLINK20"] = "1"
from pymavlink.dialects.v20 import ardupilotmega as mav  # noqa: E402


def main():
    for line in sys.stdin:
        data = bytes.fromhex(line.strip())
        parser = mav.MAVLink(None)
        parser.robust_parsing = True
        msgs = parser.parse_buffer(data) or []
        if not msgs:
            print("none")
        for m in msgs:
            print(m.get_type(), len(m.get_msgbuf()))


main()
