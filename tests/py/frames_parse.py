"""Parses frames given as hex lines on stdin with pymavlink (the ardupilotmega dialect,
MAVLink 2 parser, no signing key), one datagram per line, and prints per frame:
`msgid crc_ok length signed` (crc_ok is `-` for ids pymavlink's dialect lacks, whose
checksum it cannot check). The independent reader of what mavtables forwarded."""

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
            continue
        for m in msgs:
            if m.get_type() == "BAD_DATA":
                reason = getattr(m, "reason", "")
                # An id pymavlink does not know: framed, checksum unknown to it.
                if "unknown MAVLink message ID" in reason:
                    print(data[7] | data[8] << 8 | data[9] << 16, "-", len(data), int(data[2] & 1))
                else:
                    print("bad", reason.replace(" ", "_"))
                continue
            hdr = m.get_header()
            print(hdr.msgId, "ok", len(m.get_msgbuf()), int(bool(m._signed)))


main()
