"""The rosbridge v2 protocol, one Session per client: pure (no tornado, no rospy, no transport). Its front is
what the transport and the node use; the details are the modules beside it:
- session.py: Session (a client's requests checked and dispatched, its state, its outgoing queue) and Config;
- reassembly.py: fragment and png ops in; subscription.py: merging and throttling a client's subscriptions;
- encoded.py: what goes out, each message encoded once for every client; outbox.py: a client's Outbox (small
  before big, each topic fresh while its socket is backed up, bounded)."""

from rosbridge.protocol.session import AUTH_TIMEOUT, Config, Session

__all__ = ["AUTH_TIMEOUT", "Config", "Session"]
