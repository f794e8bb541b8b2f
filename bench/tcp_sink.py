"""A plain TCP reader for transport_server.py --forward: it prints its port and READY, takes one connection
and reads until it closes, as a ROS subscriber reads its publisher (in 64 KB reads; nothing else)."""

import socket

listener = socket.create_server(("127.0.0.1", 0))
print("PORT", listener.getsockname()[1], "READY", flush=True)
conn, _ = listener.accept()
while conn.recv(1 << 16):
    pass
