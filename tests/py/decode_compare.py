"""Compares `mavtables inspect --json` output with pymavlink's decoding of the same tlog.

usage: decode_compare.py OURS.jsonl FILE.tlog
Prints one JSON object: how many frames were compared, the first mismatches, and which
message ids were skipped because pymavlink's dialect lacks them.
"""
import json
import math
import os
import struct
import sys

os.environ["MAVLINK20"] = "1"
from pymavlink import mavutil  # noqa: E402


def same(ours, theirs):
    if isinstance(theirs, float):
        if math.isnan(theirs) or math.isinf(theirs):
            return ours is None
        if not isinstance(ours, (int, float)):
            return False
        # `float` fields are printed in their shortest form: compare as 32-bit floats
        # when pymavlink's value is one.
        if float(ours) == theirs:
            return True
        as_f32 = struct.unpack("<f", struct.pack("<f", theirs))[0]
        return as_f32 == theirs and struct.unpack("<f", struct.pack("<f", float(ours)))[0] == theirs
    if isinstance(theirs, (list, tuple)):
        return isinstance(ours, list) and len(ours) == len(theirs) and all(same(a, b) for a, b in zip(ours, theirs))
    if isinstance(theirs, (bytes, bytearray)):
        return ours == list(theirs) or ours == theirs.decode("utf-8", "replace").rstrip("\0")
    return ours == theirs


def main():
    ours_path, tlog = sys.argv[1], sys.argv[2]
    with open(ours_path) as f:
        ours = [json.loads(line) for line in f]
    mlog = mavutil.mavlink_connection(tlog, dialect="ardupilotmega")
    compared, mismatches, skipped_ours, theirs_unknown = 0, [], {}, 0
    fields_compared = 0
    i = 0
    while True:
        m = mlog.recv_msg()
        if m is None:
            break
        if m.get_type() == "BAD_DATA" or m.get_type().startswith("UNKNOWN"):
            theirs_unknown += 1
            continue
        key = (m.get_msgId(), m.get_seq(), m.get_srcSystem(), m.get_srcComponent())
        # Our frames that pymavlink did not report (ids its dialect lacks) are skipped.
        while i < len(ours) and (ours[i]["msg_id"], ours[i]["seq"], ours[i]["sys"], ours[i]["comp"]) != key:
            skipped_ours[ours[i]["msg_id"]] = skipped_ours.get(ours[i]["msg_id"], 0) + 1
            i += 1
        if i == len(ours):
            mismatches.append({"missing_in_ours": list(key)})
            break
        o = ours[i]
        i += 1
        compared += 1
        if o["name"] != m.get_type():
            mismatches.append({"index": i - 1, "name": [o["name"], m.get_type()]})
            continue
        for name, value in m.to_dict().items():
            if name == "mavpackettype":
                continue
            if name not in o["fields"]:
                mismatches.append({"index": i - 1, "msg": o["name"], "field_missing": name})
                continue
            fields_compared += 1
            if not same(o["fields"][name], value):
                mismatches.append({"index": i - 1, "msg": o["name"], "field": name,
                                   "ours": o["fields"][name], "theirs": repr(value)})
        if len(mismatches) > 20:
            break
    while i < len(ours):
        skipped_ours[ours[i]["msg_id"]] = skipped_ours.get(ours[i]["msg_id"], 0) + 1
        i += 1
    print(json.dumps({
        "compared": compared,
        "fields_compared": fields_compared,
        "mismatches": mismatches[:20],
        "skipped_ours": {str(k): v for k, v in sorted(skipped_ours.items())},
        "theirs_unknown": theirs_unknown,
    }))


main()
