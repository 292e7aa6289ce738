"""Makes and reads small PX4 ulog files for the flight log tests.

usage:
  ulog_log.py make OUT [--samples N]   writes a valid ulog: the file header, flag bits,
                                       a format, info and parameters (the definitions),
                                       then one subscription and N data samples
  ulog_log.py split FILE               prints where the definitions end (the offset of
                                       the first subscription message)
  ulog_log.py read FILE                reads FILE with pyulog: "samples N" (of the one
                                       topic), "params N" and "dropouts N"

A message is its size (u16, body only), its type (one byte) and its body.
"""
import struct
import sys

MAGIC = b"ULog\x01\x12\x35"


def message(kind, body):
    return struct.pack("<HB", len(body), ord(kind)) + body


def make(out, samples):
    data = bytearray(MAGIC + b"\x01" + struct.pack("<Q", 1_000_000))
    data += message("B", bytes(8) + bytes(8) + bytes(24))
    data += message(
        "F", b"vehicle_attitude:uint64_t timestamp;float roll;float pitch;float yaw;uint32_t n;"
    )
    key = b"char[8] sys_name"
    data += message("I", bytes([len(key)]) + key + b"mavtable")
    for i in range(30):
        key = b"float SIM_P%03d" % i
        data += message("P", bytes([len(key)]) + key + struct.pack("<f", float(i)))
    data += message("A", struct.pack("<BH", 0, 0) + b"vehicle_attitude")
    for i in range(samples):
        body = struct.pack("<HQfffI", 0, 1_000_000 + i * 4000, i * 0.01, -i * 0.02, i * 0.5, i)
        data += message("D", body)
    with open(out, "wb") as f:
        f.write(data)


def split(path):
    data = open(path, "rb").read()
    at = 16
    while at + 3 <= len(data):
        size, kind = struct.unpack_from("<HB", data, at)
        if chr(kind) == "A":
            print(at)
            return
        at += 3 + size
    print(len(data))


def read(path):
    from pyulog import ULog

    log = ULog(path)
    samples = sum(len(d.data["timestamp"]) for d in log.data_list)
    print("samples", samples)
    print("params", len(log.initial_parameters))
    print("dropouts", len(log.dropouts))
    for d in log.data_list:
        ns = list(d.data["n"])
        print("increasing", all(b > a for a, b in zip(ns, ns[1:])))


def main():
    args = sys.argv[1:]
    if args[:1] == ["make"]:
        samples = 2000
        if "--samples" in args:
            samples = int(args[args.index("--samples") + 1])
        make(args[1], samples)
    elif args[:1] == ["split"]:
        split(args[1])
    elif args[:1] == ["read"]:
        read(args[1])
    else:
        sys.exit(__doc__)


if __name__ == "__main__":
    main()
