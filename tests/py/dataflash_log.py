"""Makes and reads small ArduPilot dataflash logs for the flight log tests.

usage:
  dataflash_log.py make OUT [--records N]   writes a valid log: FMT records (for FMT,
                                            PARM, ATT), PARM records, then N ATT records
  dataflash_log.py read FILE                reads FILE with pymavlink's DFReader and prints
                                            one line per message type: NAME COUNT, then
                                            "total N"

Each record is 0xA3 0x95, its type, then its fields (little-endian); an FMT record
describes a type: type, length (header included), name (4), format (16), columns (64).
"""
import os
import struct
import sys

os.environ["MAVLINK20"] = "1"

HEAD = b"\xa3\x95"
FMT_TYPE, PARM_TYPE, ATT_TYPE = 128, 64, 30


def fmt_record(typ, name, fmt, columns, length):
    return HEAD + struct.pack(
        "<BBB4s16s64s",
        FMT_TYPE,
        typ,
        length,
        name.encode(),
        fmt.encode(),
        columns.encode(),
    )


def make(out, records):
    data = bytearray()
    data += fmt_record(FMT_TYPE, "FMT", "BBnNZ", "Type,Length,Name,Format,Columns", 89)
    data += fmt_record(PARM_TYPE, "PARM", "QNf", "TimeUS,Name,Value", 3 + 8 + 16 + 4)
    data += fmt_record(ATT_TYPE, "ATT", "Qfff", "TimeUS,Roll,Pitch,Yaw", 3 + 8 + 12)
    t = 1_000_000
    for i in range(20):
        data += HEAD + struct.pack("<BQ16sf", PARM_TYPE, t, b"SIM_P%03d" % i, float(i))
        t += 100
    for i in range(records):
        data += HEAD + struct.pack(
            "<BQfff", ATT_TYPE, t, i * 0.01, -i * 0.02, (i % 360) * 1.0
        )
        t += 2500
    with open(out, "wb") as f:
        f.write(data)


def read(path):
    from pymavlink import DFReader

    log = DFReader.DFReader_binary(path, zero_time_base=True)
    counts = {}
    while True:
        m = log.recv_msg()
        if m is None:
            break
        name = m.get_type()
        counts[name] = counts.get(name, 0) + 1
    for name in sorted(counts):
        print(name, counts[name])
    print("total", sum(counts.values()))


def main():
    args = sys.argv[1:]
    if args[:1] == ["make"]:
        records = 3000
        if "--records" in args:
            records = int(args[args.index("--records") + 1])
        make(args[1], records)
    elif args[:1] == ["read"]:
        read(args[1])
    else:
        sys.exit(__doc__)


if __name__ == "__main__":
    main()
