"""The web page's files, served from web_root: only the page's own kinds of file, never outside web_root
(symlinks included), never the npm tree or dot files, and with headers that stop a browser from sniffing types
or another site from framing the page (a framed control page could be clicked into driving the robot)."""

import os
import re

import tornado.web

from rosbridge.origins import SECURITY_HEADERS

PAGE_FILE_KINDS = {".html", ".js", ".mjs", ".css", ".png", ".svg", ".ico", ".jpg", ".jpeg", ".webp", ".woff2", ".map"}
HIDDEN_FOLDERS = {"node_modules"}
VENDOR_FILE = re.compile(r"\bvendor/([\w.-]+)")  # how the page's own files name a library (tools/setup installs them)


class PageFiles(tornado.web.StaticFileHandler):
    def set_default_headers(self):
        for name, value in SECURITY_HEADERS.items():
            self.set_header(name, value)

    def validate_absolute_path(self, root, absolute_path):
        real_root = os.path.realpath(root)
        real = os.path.realpath(absolute_path)
        relative = os.path.relpath(real, real_root).split(os.sep)
        if (
            relative[0] == os.pardir
            or any(part.startswith(".") or part in HIDDEN_FOLDERS for part in relative)
            or os.path.splitext(real)[1].lower() not in PAGE_FILE_KINDS
        ):
            raise tornado.web.HTTPError(404)
        return super().validate_absolute_path(root, absolute_path)


def missing_files(web_root):
    """The files of web_root/vendor/ that the page's own .html and .js files name but that are absent, sorted."""
    named = set()
    for folder, subfolders, files in os.walk(web_root):
        subfolders[:] = [
            name for name in subfolders if name not in HIDDEN_FOLDERS | {"vendor"} and not name.startswith(".")
        ]
        for name in files:
            if os.path.splitext(name)[1] in (".html", ".js"):
                with open(os.path.join(folder, name), encoding="utf-8", errors="replace") as page_file:
                    named.update(VENDOR_FILE.findall(page_file.read()))
    return sorted(name for name in named if not os.path.isfile(os.path.join(web_root, "vendor", name)))
