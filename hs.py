import socket, time
from pymavlink.dialects.v20 import common as m
g=socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
k=socket.socket(socket.AF_INET, socket.SOCK_DGRAM); k.bind(("127.0.0.1",15601)); k.settimeout(0.3)
mav=m.MAVLink(None, srcSystem=1, srcComponent=1); hm=m.MAVLink(None, srcSystem=101, srcComponent=1)
for i in range(5):
    g.sendto(m.MAVLink_heartbeat_message(1,0,0,0,0,3).pack(mav),("127.0.0.1",15600))
    try:
        d,a=k.recvfrom(2048); print("sink got",len(d),"from",a); k.sendto(m.MAVLink_heartbeat_message(6,8,0,0,0,3).pack(hm),a)
    except Exception as e: print("timeout")
for i in range(3):
    g.sendto(m.MAVLink_command_long_message(101,1,511,0,1,2,3,4,5,6,7).pack(mav),("127.0.0.1",15600))
    try:
        d,a=k.recvfrom(2048); print("sink got",len(d),"from",a, d[:12].hex())
    except Exception as e: print("timeout2")
