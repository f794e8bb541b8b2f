"""Accepting connections without failing in a loop when file descriptors run short: used for the websocket
clients (server.py) and for the subscribers of the bridge's topics (ros_side/links.py)."""
import errno
import os
import resource

FDS_KEPT_FREE = 64  # file descriptors kept for what is not accepted here (rospy's, service calls)


def accept_connections(handle_connection, sockets, log, loop):
    """Accepts clients like Tornado's TCPServer.add_sockets, but when file descriptors run short (EMFILE,
    ENFILE, or fewer than FDS_KEPT_FREE left) it stops listening for a while instead of failing in a loop:
    the pending clients wait in the kernel's backlog."""
    soft_limit = resource.getrlimit(resource.RLIMIT_NOFILE)[0]

    def fds_short():
        if soft_limit == resource.RLIM_INFINITY:
            return False
        return len(os.listdir("/proc/self/fd")) > soft_limit - FDS_KEPT_FREE

    def pause(sock, text):
        log(f"not accepting connections for a second: {text}")
        loop.remove_handler(sock)
        loop.call_later(1.0, lambda: loop.add_handler(sock, lambda fd, events: accept(sock), loop.READ))

    def accept(sock):
        for _ in range(128):  # then let the loop serve the clients it has
            if fds_short():
                pause(sock, f"file descriptors near the limit ({soft_limit})")
                return
            try:
                connection, address = sock.accept()
            except BlockingIOError:
                return
            except OSError as error:
                if error.errno == errno.ECONNABORTED:
                    continue
                if error.errno in (errno.EMFILE, errno.ENFILE, errno.ENOBUFS, errno.ENOMEM):
                    pause(sock, error.strerror)
                    return
                raise
            handle_connection(connection, address)  # (TCPServer's own per-connection set-up)

    for sock in sockets:
        loop.add_handler(sock, lambda fd, events, sock=sock: accept(sock), loop.READ)
