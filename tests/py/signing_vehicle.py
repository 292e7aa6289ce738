"""tests/py/vehicle.py with MAVLink 2 signing: the same simulated quadrotor (HEARTBEATs,
300 parameters, COMMAND_LONG, FTP NAKs), but it signs everything it sends with KEY and
refuses every frame that is not signed with KEY (pymavlink's allow_unsigned_callback
says no), for the ground station sessions of tests/e2e/signing_peers.rs.

usage:
  signing_vehicle.py LINK --key HEX [--link-id N] [--params N] [--sys S] [--comp C]

LINK as for vehicle.py (--serial, --udp, --udp-listen, --tcp, --tcp-listen). Output as
for vehicle.py, plus
  rejected REASON             a frame pymavlink refused (bad or missing signature)
  signing sig=N good=N bad=N unsigned=N reject=N
                              pymavlink's signing counters, just before "end"
"""
import argparse
import os
import signal
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import vehicle  # noqa: E402

EPOCH_2015 = 1420070400


class SigningVehicle(vehicle.Vehicle):
    def __init__(self, link, sysid, compid, count, key, link_id):
        super().__init__(link, sysid, compid, count)
        s = self.mav.signing
        s.secret_key = key
        s.sign_outgoing = True
        s.link_id = link_id
        s.timestamp = int((time.time() - EPOCH_2015) * 100000)
        s.allow_unsigned_callback = lambda _mav, _msgid: False

    def handle(self, msg):
        if msg.get_type() == "BAD_DATA" and "signature" in str(msg.reason).lower():
            vehicle.say("rejected %s" % msg.reason)
            return
        super().handle(msg)

    def stats(self):
        s = self.mav.signing
        vehicle.say("signing sig=%d good=%d bad=%d unsigned=%d reject=%d" % (
            s.sig_count, s.goodsig_count, s.badsig_count, s.unsigned_count, s.reject_count))


def main():
    parser = argparse.ArgumentParser()
    where = parser.add_mutually_exclusive_group(required=True)
    where.add_argument("--serial")
    where.add_argument("--udp")
    where.add_argument("--udp-listen")
    where.add_argument("--tcp")
    where.add_argument("--tcp-listen")
    parser.add_argument("--key", required=True)
    parser.add_argument("--link-id", type=int, default=0)
    parser.add_argument("--sys", type=int, default=1)
    parser.add_argument("--comp", type=int, default=1)
    parser.add_argument("--params", type=int, default=300)
    args = parser.parse_args()

    def stop(_signum, _frame):
        raise SystemExit(0)

    signal.signal(signal.SIGTERM, stop)
    if args.serial:
        link = vehicle.Pty(args.serial)
    elif args.udp:
        link = vehicle.UdpOut(args.udp)
    elif args.udp_listen:
        link = vehicle.UdpListen(args.udp_listen)
    elif args.tcp:
        link = vehicle.TcpClient(args.tcp)
    else:
        link = vehicle.TcpListen(args.tcp_listen)
    v = SigningVehicle(link, args.sys, args.comp, args.params,
                       bytes.fromhex(args.key), args.link_id)
    try:
        v.run()
    finally:
        v.stats()
        link.close()
        vehicle.say("end")


if __name__ == "__main__":
    main()
