"""Reads a .tlog with pymavlink, as a ground station would (tests/recording_e2e.rs).

usage: tlog_read.py FILE...

For each message of each file, in order, prints "FILE_INDEX TIMESTAMP_US HEX": the
record's timestamp (microseconds since the UNIX epoch, as pymavlink read it) and the
frame's bytes. A record pymavlink cannot decode is printed as "BAD_DATA ...", which the
tests count as a failure.
"""
import os
import sys

os.environ["MAVLINK20"] = "1"
from pymavlink import mavutil  # noqa: E402


def main():
    for index, path in enumerate(sys.argv[1:]):
        log = mavutil.mavlink_connection(path, dialect="ardupilotmega")
        while True:
            msg = log.recv_msg()
            if msg is None:
                break
            stamp = int(round(msg._timestamp * 1e6))
            line = "%d %d %s" % (index, stamp, bytes(msg.get_msgbuf()).hex())
            if msg.get_type() == "BAD_DATA":
                line = "BAD_DATA " + line
            sys.stdout.write(line + "\n")
    sys.stdout.flush()


if __name__ == "__main__":
    main()
