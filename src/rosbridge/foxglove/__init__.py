"""The Foxglove WebSocket protocol (`foxglove.websocket.v1`, also named `foxglove.sdk.v1`) with ROS 1 data, beside
rosbridge (protocol/) over the same transport and ROS side; the transport chooses it by the subprotocol a client
offers. Pure: no tornado, no rospy. Its parts:
- session.py: FoxgloveSession, one client (its requests, subscriptions, client channels, outbox);
- catalog.py: Catalog, what every Foxglove client is told alike (channels, services, graph, parameter updates);
- wire.py: the binary messages both ways; parameters.py: parameter values both ways."""

from rosbridge.foxglove.catalog import Catalog
from rosbridge.foxglove.session import FoxgloveSession
from rosbridge.foxglove.wire import SUBPROTOCOLS

__all__ = ["SUBPROTOCOLS", "Catalog", "FoxgloveSession"]
