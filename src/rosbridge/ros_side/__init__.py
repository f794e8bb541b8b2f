"""The ROS side of the bridge: the topics, services and service calls that the clients' requests need, shared by
every client with reference counts (holders.py).

Files: backend.py (RosBackend, the protocol's backend: a short front over the rest), publishers.py (client ->
ROS topics), subscribers.py (ROS -> client topics), links.py (the topics' TCPROS connections with other nodes,
on the loop), services.py (calls out, and services that clients provide), worker.py (the thread for work that
can block), recovery.py (registering again with a restarted master), master_proxy.py (XML-RPC for the
threads that poll the master), holders.py (who holds what; pure).

Threads, what each may touch, and how work crosses between them:
- The event loop (one thread): every Session, RosBackend and the managers' tables; every topic connection
  (links.py: reading from publishers, writing to subscribers, the handshakes) and what a topic keeps for them
  (a publisher's subscribers, its latched message and early replay; a subscriber's latched message); every
  timer. Nothing here asks the master or makes a rospy object. The messages of one read of a publisher are
  delivered in the server's `delivery` context (write_turns.py), DELIVERY_BATCH at a time
  (subscribers.py): the clients write them when it ends.
- The worker (one thread, RosWorker): asks the master (GraphSnapshot, only it touches that) and makes and drops
  rospy subscribers, publishers and services, in the order the loop submitted them. Each job's outcome goes
  back to the loop (IOLoop.add_callback), and after it the requests a client sent meanwhile, held by
  its Session until the ROS work before them is done (RosWorker.after_submitted); an object's fields written by
  a job (`_subscriber`, `_publisher`, `server`) are read only by later jobs or after the loop got the outcome.
  It writes TopicLinks' two tables (a topic's entry before its rospy object is made, and removed before it is
  dropped); rospy's threads and the loop only read them (single dict operations).
- rospy's threads (its XML-RPC server, its connecting threads) call TopicLinks as a protocol handler:
  create_transport resolves the publisher's address there, adds the link to rospy's list and hands the link
  to the loop (IOLoop.add_callback) to connect; init_publisher only reads the table. rospy may close a link
  from its threads (when the topic is unregistered): Link.close marks it done and hands the closing of its
  stream to the loop. A message never crosses a thread.
- Service-call threads (ServiceCalls), one per call in flight, bounded per client and in total, kept a minute
  for the next call and started by a starter thread of their own, never by the loop (off_loop.CallThreads):
  each calls a ROS service or rosapi and hands its answer to the loop (IOLoop.add_callback); the counters of
  calls in flight are only touched on the loop.
- rospy's service threads for services that clients provide (ProvidedServices._serve): each puts the call on
  the loop (add_callback) and blocks on a concurrent.futures.Future that only the loop resolves."""

from rosbridge.ros_side.backend import RosBackend

__all__ = ["RosBackend"]
