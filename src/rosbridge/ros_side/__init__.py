"""The ROS side of the bridge: the rospy publishers, subscribers, service servers and service calls that the
clients' requests need, shared by every client with reference counts (holders.py).

Files: backend.py (RosBackend, the protocol's backend: a short front over the rest), publishers.py (client ->
ROS topics), subscribers.py (ROS -> client topics), services.py (calls out, and services that clients provide),
worker.py (the thread for work that can block), recovery.py (registering again with a restarted master),
holders.py (who holds what; pure).

Threads, what each may touch, and how work crosses between them:
- The event loop (one thread): every Session, RosBackend and the managers' tables; the subscribers' drain; every
  timer. Nothing here asks the master or makes a rospy object.
- The worker (one thread, RosWorker): asks the master (GraphSnapshot, only it touches that) and makes and drops
  rospy subscribers, publishers and services, in the order the loop submitted them. Each job's outcome goes
  back to the loop (IOLoop.add_callback); an object's fields written by a job (`_subscriber`, `_publisher`,
  `server`) are read only by later jobs or after the loop got the outcome.
- rospy's receiving threads, one per connection to a publisher: TopicSubscriber.on_message only appends the
  message (its bytes, rosbridge.wire.raw_class) to the topic's inbox (a deque: append/popleft are atomic) and, if `wake_pending` is False, sets it and asks the
  loop (IOLoop.add_callback, thread-safe) to drain. The loop clears `wake_pending` before it reads how much to
  drain, so a message appended meanwhile is either drained now or wakes the loop again.
- One publishing thread per client-advertised topic (ClientPublisher), started by the worker once the rospy
  publisher exists: the loop appends messages, serialized (immutable bytes), to its queue (a deque) and sets an
  Event; the thread pops and publishes. `_closed` is written by the loop and read by the thread after the Event:
  set once, never cleared.
- rospy's subscriber-listener callbacks (peer_subscribe / peer_unsubscribe, on rospy's threads) and the
  publishing thread both use EarlyReplay's buffer: every read and write of it holds EarlyReplay's lock.
- Service-call threads (ServiceCalls), one per call in flight, bounded per client and in total: each calls a
  ROS service or rosapi and hands its answer to the loop (IOLoop.add_callback); the counters of calls in flight
  are only touched on the loop.
- rospy's service threads for services that clients provide (ProvidedServices._serve): each puts the call on
  the loop (add_callback) and blocks on a concurrent.futures.Future that only the loop resolves."""
from rosbridge.ros_side.backend import RosBackend

__all__ = ["RosBackend"]
