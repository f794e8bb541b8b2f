"""Services: calls from clients to ROS services (and rosapi), and ROS services whose answers come from a client."""

import collections
import concurrent.futures
import functools
import itertools
import threading

import genpy
import rosgraph
import rospy
import rosservice

from rosbridge.codec.json_values import ConversionError, from_json, request_from_args, to_json
from rosbridge.errors import RequestError, refusal_text
from rosbridge.message_types import service_class
from rosbridge.off_loop import CallThreads

ABORT_RETRY_S = 1.0  # an ended call's connection is closed again this often until its thread has returned


class ServiceCalls:
    """Client -> ROS service calls, each on a thread of its own while it runs (off_loop.CallThreads) so that a
    slow or silent service holds only its own callers. Bounded: at most max_running calls of one client run at
    once (a call's thread counts until it returns), at most max_total in all, but for one call of each client
    that runs none (so that clients whose calls hang cannot take every turn: max_total plus one per client); the
    others wait, in turns between clients, and one client may have at most max_pending calls in all. A call to a
    ROS service ends when its client's timeout comes or its client leaves: its connection to the service is closed
    (_Running.abort), so that a service that never answers holds no thread and no turn for good."""

    def __init__(self, loop, rosapi, max_running, max_total, max_pending):
        self._loop, self._rosapi = loop, rosapi
        self._max_running, self._max_total, self._max_pending = max_running, max_total, max_pending
        # only touched on the loop:
        self._running = {}  # session -> its calls still running (_Running)
        self._total = 0
        self._waiting = collections.OrderedDict()  # session -> deque of (start, answer); the next turn first
        self._threads = CallThreads("service call")

    def call(self, session, service, args, type_name, timeout, reply):
        rosapi = self._rosapi is not None and self._rosapi.handles(service)
        work = (
            functools.partial(self._rosapi.call, service, args)
            if rosapi
            else functools.partial(_call_ros_service, service, args, type_name)
        )
        text = f"Service {service} timed out after {timeout} s"
        self.run(session, f"call_service {service}", work, reply, timeout, text, through_proxy=not rosapi)

    def run(self, session, what, work, reply, timeout=None, timeout_text=None, through_proxy=False):
        """Runs work() (it may block: a service, the master) in the client's turn, within the bounds; reply(True,
        its result) or reply(False, the text of what it raised, or timeout_text after timeout s) later, on the
        loop. through_proxy: work(call) calls a ROS service through a ServiceProxy it hands to call.hold first,
        which ends it when the timeout comes or the client leaves."""
        running, waiting = len(self._running.get(session, ())), self._waiting.get(session, ())
        if running + len(waiting) >= self._max_pending:
            raise RequestError(
                f"{what}: refused, this client has {running + len(waiting)} calls pending (at most {self._max_pending})"
            )
        answer = _Answer(self._loop, reply)
        if timeout is not None:
            answer.time_out(timeout, timeout_text)
        self._waiting.setdefault(session, collections.deque()).append(
            (functools.partial(self._start, session, work, answer, through_proxy), answer)
        )
        self._start_waiting()

    def release(self, session):
        """The client left: its waiting calls are dropped, and its running ones ended (unheard)."""
        for _, answer in self._waiting.pop(session, ()):
            answer.cancel()
        for running in self._running.get(session, ()):
            running.abort()

    def _start_waiting(self):
        for session in list(self._waiting):  # clients in turns: one that starts a call goes to the back
            running = len(self._running.get(session, ()))
            if running < self._max_running and (running == 0 or self._total < self._max_total):
                queue = self._waiting.pop(session)
                start, _ = queue.popleft()
                if queue:
                    self._waiting[session] = queue
                start()

    def _start(self, session, work, answer, through_proxy):
        running = answer.running = _Running(self._loop)
        self._running.setdefault(session, set()).add(running)
        self._total += 1
        if through_proxy:
            work = functools.partial(work, running)

        def run():  # on the call's thread
            try:
                result = (True, work())
            except Exception as error:  # the service's failure, told to the client
                result = (False, str(error) or repr(error))
            self._loop.add_callback(self._finished, session, running, answer, *result)

        self._threads.run(run)

    def _finished(self, session, running, answer, ok, values):
        running.finished()
        self._total -= 1
        calls = self._running[session]
        calls.discard(running)
        if not calls:
            del self._running[session]
        answer(ok, values)
        self._start_waiting()


class _Running:
    """A call running on its thread. One that calls a ROS service hands it the ServiceProxy it calls through
    (hold); abort() closes the proxy's connection, which makes rospy's blocked read fail and the thread return.
    An abort that comes while rospy is still connecting finds nothing to close yet: it closes again every
    ABORT_RETRY_S until the thread has returned."""

    __slots__ = ("_loop", "_lock", "_proxy", "_aborted", "_timer")

    def __init__(self, loop):
        self._loop, self._lock = loop, threading.Lock()
        self._proxy, self._aborted, self._timer = None, False, None

    def hold(self, proxy):
        """On the call's thread, before calling through proxy."""
        with self._lock:
            self._proxy, aborted = proxy, self._aborted
        if aborted:
            raise RequestError("the call was ended before it began")

    def abort(self):
        """On the loop: ends the call (its client left, or its timeout came)."""
        with self._lock:
            self._aborted, proxy = True, self._proxy
        if proxy is not None:
            proxy.close()
        if self._timer is None:
            self._timer = self._loop.call_later(ABORT_RETRY_S, self._again)

    def _again(self):
        self._timer = None
        self.abort()

    def finished(self):
        """On the loop: the call's thread has returned."""
        if self._timer is not None:
            self._loop.remove_timeout(self._timer)
            self._timer = None


class _Answer:
    """Replies once: with the call's result or with the timeout, whichever comes first; then drops the timer
    (a timer left behind would hold the reply and the client's session for as long as the timeout). At the
    timeout the call, if it runs, is ended."""

    __slots__ = ("_loop", "_reply", "_timer", "running")

    def __init__(self, loop, reply):
        self._loop, self._reply, self._timer = loop, reply, None
        self.running = None  # the _Running of the call once it started

    def __call__(self, ok, values):
        if self._reply is None:
            return
        reply, self._reply = self._reply, None
        if self._timer is not None:
            self._loop.remove_timeout(self._timer)
            self._timer = None
        reply(ok, values)

    def time_out(self, seconds, text):
        self._timer = self._loop.call_later(seconds, functools.partial(self._timed_out, text))

    def _timed_out(self, text):
        self._timer = None
        self(False, text)
        if self.running is not None:
            self.running.abort()

    def cancel(self):
        """Never replies (the client left)."""
        self._reply = None
        if self._timer is not None:
            self._loop.remove_timeout(self._timer)
            self._timer = None


def _call_ros_service(service, args, type_name, call):
    """On a call's thread: the service's response as JSON, or an exception whose text goes to the client."""
    if type_name is None:
        type_name = rosservice.get_service_type(service)
        if type_name is None:
            raise RequestError(f"Service {service} does not exist")
    cls = service_class(type_name)
    request = request_from_args(cls._request_class, args, now=rospy.Time.now)
    return to_json(_call_through(call, service, cls, request))


def _call_through(call, service, cls, request):
    """Calls `service` through a proxy that `call` (a _Running) holds, so that closing it ends the call."""
    proxy = rospy.ServiceProxy(service, cls, persistent=True)  # (persistent: the proxy keeps the connection)
    call.hold(proxy)
    try:
        return proxy(request)
    except rospy.ServiceException as error:
        raise RequestError(f"Service {service} failed: {error}") from None
    finally:
        proxy.close()


class _RawMessage(genpy.Message):
    """A request or response as its serialized bytes: what rospy writes and reads for a call whose bytes a
    client gives (the Foxglove protocol's `ros1` encoding) and gets back as they are."""

    __slots__ = ("data",)
    _has_header = False
    _full_text = ""

    def __init__(self, data=b""):  # (not genpy's: there are no fields)
        self.data = data

    def serialize(self, buffer):
        buffer.write(self.data)

    def deserialize(self, data):
        self.data = bytes(data)
        return self


def call_raw_service(service, type_name, data, call):
    """On a call's thread: calls `service` with a request's ROS bytes; its response's ROS bytes."""
    cls = service_class(type_name)
    raw = type(cls.__name__, (), {"_type": cls._type, "_md5sum": cls._md5sum})
    raw._request_class = type("Request", (_RawMessage,), {"_type": cls._request_class._type, "_md5sum": cls._md5sum})
    raw._response_class = type("Response", (_RawMessage,), {"_type": cls._response_class._type, "_md5sum": cls._md5sum})
    return _call_through(call, service, raw, raw._request_class(data)).data


class _ProvidedService:
    """A ROS service whose answers come from one websocket client."""

    __slots__ = ("name", "client_name", "type", "cls", "session", "server", "pending")

    def __init__(self, name, client_name, type_name, cls, session):
        self.name, self.type, self.cls, self.session = name, type_name, cls, session
        self.client_name = client_name  # as the client spelled it: its library routes our calls by that name
        self.pending = {}  # call id -> concurrent.futures.Future waited on by a rospy thread
        self.server = None


class ProvidedServices:
    """ROS services provided by clients: a ROS call is forwarded to the client (call_service op) and answered
    with its service_response. The rospy service is made and shut down on the worker."""

    def __init__(self, loop, worker, service_timeout):
        self._loop, self._worker, self._service_timeout = loop, worker, service_timeout
        self._services = {}
        self._call_ids = itertools.count(1)

    def advertise(self, session, service, client_name, type_name):
        """service: the resolved name; client_name: as the client wrote it."""
        cls = service_class(type_name)
        entry = self._services.get(service)
        if entry is not None:
            if entry.session is session and entry.type == type_name:
                return
            self._shutdown(entry, "advertised again by another client")
        entry = self._services[service] = _ProvidedService(service, client_name, type_name, cls, session)
        self._worker.submit(lambda: self._make(entry), lambda error, _: self._made(entry, error))

    def _make(self, entry):
        """On the worker: refuse a service another node provides, then make ours."""
        me = rospy.get_name()
        for name, providers in rosgraph.Master(me).getSystemState()[2]:
            if name == entry.name and any(p != me for p in providers):
                raise RequestError(f"advertise_service {entry.name}: already provided by {', '.join(providers)}")
        entry.server = rospy.Service(entry.name, entry.cls, lambda request: self._serve(entry, request))

    def _made(self, entry, error):
        if error is None:
            if self._services.get(entry.name) is not entry:  # unadvertised while it was being made
                self._worker.submit(lambda: entry.server.shutdown("unadvertised by its client"))
            return
        if self._services.get(entry.name) is entry:
            del self._services[entry.name]
        entry.session.ros_refused(
            "advertise_service", entry.name, refusal_text(error, f"advertising service {entry.name}")
        )

    def unadvertise(self, session, service):
        entry = self._services.get(service)
        if entry is None or entry.session is not session:
            raise RequestError(f"unadvertise_service {service}: not advertised by this client")
        self._shutdown(entry, "unadvertised by its client")

    def _shutdown(self, entry, why):
        del self._services[entry.name]
        server = entry.server
        if server is not None:  # (else it is still being made: _made shuts it down)
            self._worker.submit(lambda: server.shutdown(why))
        for future in entry.pending.values():
            if not future.done():
                future.set_exception(rospy.ServiceException(f"service {entry.name} {why}"))
        entry.pending.clear()

    def _serve(self, entry, request):
        """On a rospy thread: forward the call to the client and wait for its service_response."""
        future = concurrent.futures.Future()
        self._loop.add_callback(self._forward_call, entry, request, future)
        try:
            return future.result(timeout=self._service_timeout)
        except concurrent.futures.TimeoutError:
            raise rospy.ServiceException(
                f"service {entry.name}: the client did not answer within {self._service_timeout} s"
            ) from None

    def _forward_call(self, entry, request, future):
        if self._services.get(entry.name) is not entry:
            future.set_exception(rospy.ServiceException(f"service {entry.name} is no longer provided"))
            return
        call_id = f"service_request:{entry.name}:{next(self._call_ids)}"
        entry.pending[call_id] = future
        future.add_done_callback(lambda _: self._loop.add_callback(entry.pending.pop, call_id, None))
        entry.session.request_service(call_id, entry.client_name, to_json(request))

    def respond(self, session, service, call_id, result, values):
        entry = self._services.get(service)
        if entry is None or entry.session is not session:
            raise RequestError(f"service_response {service}: not advertised by this client")
        future = entry.pending.pop(call_id, None)
        if future is None or future.done():
            raise RequestError(f"service_response {service}: no call with id {call_id!r} is waiting")
        if not result:
            # As the reference: an object still answers the ROS caller (roslibpy's examples return False from
            # handlers that fill the response); anything else fails the call, an error text as the reason.
            if not isinstance(values, dict):
                reason = (
                    values
                    if isinstance(values, str)
                    else f"service {service}: the client answered result=false: {values}"
                )
                future.set_exception(rospy.ServiceException(reason))
                return
            session.status(
                "warning",
                f"service_response {service}: result is false, but its values are an "
                "object: they are the ROS caller's response",
                call_id,
            )
        try:
            response = from_json(entry.cls._response_class, {} if values is None else values)
        except ConversionError as error:
            future.set_exception(rospy.ServiceException(f"service {service}: invalid response: {error}"))
            raise RequestError(f"service_response {service}: {error}") from None
        future.set_result(response)

    def release(self, session):
        for entry in list(self._services.values()):
            if entry.session is session:
                self._shutdown(entry, "lost its client (disconnected)")
