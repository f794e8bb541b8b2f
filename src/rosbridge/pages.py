"""The web page's files, served from web_root: only the page's own kinds of file, never outside web_root
(symlinks included), never the npm tree or dot files, and with headers that stop a browser from sniffing types
or another site from framing the page (a framed control page could be clicked into driving the robot)."""
import os

import tornado.web

SECURITY_HEADERS = {
    "X-Content-Type-Options": "nosniff",
    "X-Frame-Options": "DENY",
    "Content-Security-Policy": "frame-ancestors 'none'",
}
PAGE_FILE_KINDS = {".html", ".js", ".mjs", ".css", ".png", ".svg", ".ico", ".jpg", ".jpeg", ".webp", ".woff2",
                   ".map"}
HIDDEN_FOLDERS = {"node_modules"}


class PageFiles(tornado.web.StaticFileHandler):
    def set_default_headers(self):
        for name, value in SECURITY_HEADERS.items():
            self.set_header(name, value)

    def validate_absolute_path(self, root, absolute_path):
        real_root = os.path.realpath(root)
        real = os.path.realpath(absolute_path)
        relative = os.path.relpath(real, real_root).split(os.sep)
        if (relative[0] == os.pardir or any(part.startswith(".") or part in HIDDEN_FOLDERS for part in relative)
                or os.path.splitext(real)[1].lower() not in PAGE_FILE_KINDS):
            raise tornado.web.HTTPError(404)
        return super().validate_absolute_path(root, absolute_path)
