"""The bag recorder over HTTP (bag_recorder.py does the recording), under the same access rules as the websocket
(access.py; topics_glob in bag_recorder.py):

    GET    /bags                   the recorder's state: the recording, the black box, the bags (JSON)
    POST   /bags/record            {"topics": [...], "name": optional}: start recording
    POST   /bags/stop              stop recording
    POST   /bags/blackbox          {"topics": [...]}: keep the last blackbox_seconds of these ([]: off)
    POST   /bags/blackbox/save     {"name": optional}: write the black box into a new bag
    GET    /bags/<name>.bag        download (Range requests too)
    DELETE /bags/<name>.bag        delete

A POST must carry JSON (Content-Type application/json): a page of another site cannot send that, nor DELETE,
without asking first (CORS), which the bridge never allows. Errors come back as {"error": text} with a 4xx."""

import json

import tornado.concurrent
import tornado.web

from rosbridge.errors import ClientError
from rosbridge.http.access import EndpointHandler, refusal
from rosbridge.http.bag_recorder import Busy, bag_path

MAX_BODY = 64 * 1024  # the largest request body of any endpoint: the server refuses larger ones (413)


class _BagHandler(EndpointHandler):
    def initialize(self, bridge, recorder):
        self.bridge, self.recorder = bridge, recorder

    def prepare(self):
        refused = refusal(self.bridge, self.request, "the bag recorder")
        if refused is None and self.recorder is None:
            refused = 404, "the bag recorder is off: start the bridge with bag_folder set (see the README)"
        if refused is not None:
            self.answer_error(*refused)

    def answer_error(self, status, text):
        self.set_status(status)
        self.finish({"error": text})

    def body(self):
        if self.request.headers.get("Content-Type", "").split(";")[0].strip() != "application/json":
            raise ClientError("send the request as JSON (Content-Type: application/json)")
        try:
            body = json.loads(self.request.body or b"{}")
        except ValueError as error:
            raise ClientError(f"not JSON: {error}") from None
        if not isinstance(body, dict):
            raise ClientError("send a JSON object")
        return body


class BagsState(_BagHandler):
    def get(self):
        self.finish(self.recorder.state())


class BagAction(_BagHandler):
    async def post(self, action):
        try:
            body = self.body()
            if action == "record":
                self.recorder.start(body.get("topics"), body.get("name"))
            elif action == "stop":
                self.recorder.stop()
            elif action == "blackbox":
                topics = body.get("topics")
                self.recorder.keep_blackbox(topics if topics != [] else None)
            else:  # blackbox/save
                written = tornado.concurrent.Future()
                name = self.recorder.save_blackbox(body.get("name"), then=written.set_result)
                error = await written
                if error:
                    raise ClientError(f"saving the black box into {name} failed: {error}")
        except ClientError as error:
            self.answer_error(409 if isinstance(error, Busy) else 400, str(error))
            return
        self.finish(self.recorder.state())


class BagFile(_BagHandler, tornado.web.StaticFileHandler):
    """A bag to download (StaticFileHandler: Range requests too; no ETag, a bag being recorded changes), or to
    delete."""

    def initialize(self, bridge, recorder):
        super().initialize(bridge, recorder)
        tornado.web.StaticFileHandler.initialize(self, path=str(recorder.folder) if recorder else "/nonexistent")

    async def get(self, name, include_body=True):
        try:
            self.recorder.path(name)
        except ClientError as error:
            self.answer_error(404, str(error))
            return
        self.set_header("Content-Disposition", f'attachment; filename="{name}"')
        await super().get(name, include_body)

    def get_content_type(self):
        return "application/octet-stream"

    def delete(self, name):
        try:
            bag_path(self.recorder.folder, name)
            self.recorder.delete(name)
        except ClientError as error:
            self.answer_error(404 if "no bag" in str(error) else 400, str(error))
            return
        self.finish(self.recorder.state())


def bag_routes(bridge, recorder):
    """recorder None: the recorder is off, and its addresses say so."""
    options = {"bridge": bridge, "recorder": recorder}
    return [
        (r"/bags", BagsState, options),
        (r"/bags/(record|stop|blackbox|blackbox/save)", BagAction, options),
        (r"/bags/([^/]+\.bag)", BagFile, options),
    ]
