"""A Zenoh router for the end-to-end tests: the PyPI `eclipse-zenoh` package's session
in router mode, listening on the endpoint given (e.g. tcp/127.0.0.1:7447), with no
multicast scouting. Prints `ready` once it listens and runs until its stdin closes.

    zenoh_router.py ENDPOINT
"""
import sys

import zenoh

conf = zenoh.Config()
conf.insert_json5("mode", '"router"')
conf.insert_json5("listen/endpoints", '["%s"]' % sys.argv[1])
conf.insert_json5("scouting/multicast/enabled", "false")
session = zenoh.open(conf)
print("ready", flush=True)
sys.stdin.read()
session.close()
