"""Prints, for every message of a MAVLink XML dialect file and its includes, what
pymavlink's generator (mavgen's parser, mavparse.MAVXML, MAVLink 2.0) computes:
`id name crc_extra min_len max_len`, one line each, sorted by id. The independent
side of tests/dialect_runtime.rs's cross-check."""

import contextlib
import os
import sys

from pymavlink.generator import mavparse


def files(path, seen):
    path = os.path.abspath(path)
    if path in seen:
        return
    seen.append(path)
    # mavparse prints notes about enums on stdout: keep them off our output.
    with contextlib.redirect_stdout(sys.stderr):
        xml = mavparse.MAVXML(path, mavparse.PROTOCOL_2_0)
    for inc in xml.include:
        yield from files(os.path.join(os.path.dirname(path), inc), seen)
    yield xml


def main():
    rows = {}
    for xml in files(sys.argv[1], []):
        for m in xml.message:
            rows[m.id] = (m.name, m.crc_extra, m.wire_min_length, m.wire_length)
    for mid in sorted(rows):
        name, crc, lo, hi = rows[mid]
        print(mid, name, crc, lo, hi)


main()
