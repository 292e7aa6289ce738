"""Publishes one sample on a Zenoh network, as any Zenoh client could: a client of the
Zenoh router at ENDPOINT puts the bytes given in hex under KEY, then prints `sent`.

    zenoh_publish.py ENDPOINT KEY HEX
"""
import sys

import zenoh

conf = zenoh.Config()
conf.insert_json5("mode", '"client"')
conf.insert_json5("connect/endpoints", '["%s"]' % sys.argv[1])
conf.insert_json5("scouting/multicast/enabled", "false")
session = zenoh.open(conf)
session.put(sys.argv[2], bytes.fromhex(sys.argv[3]))
print("sent", flush=True)
session.close()
