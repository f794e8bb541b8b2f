"""Assets for Foxglove clients (fetchAsset): files of ROS packages named by `package://` URIs, as a robot
description names its meshes. Only a package's own files (no `..`, no symlink out of it), of the kinds a viewer
draws, within a size bound. Read on a call thread (services.ServiceCalls.run), one file at a time for all clients,
and kept while unchanged: clients fetching the same mesh share one copy of its bytes."""

import collections
import os
import re
import stat
import threading
import time
import urllib.parse

import rospkg

from rosbridge.errors import RequestError

MAX_ASSET_BYTES = 32 * 1024 * 1024
# meshes, textures and robot descriptions (foxglove_bridge's default allowlist names the same kinds)
EXTENSIONS = frozenset(
    ("dae", "fbx", "glb", "gltf", "jpeg", "jpg", "mtl", "obj", "png", "stl", "tif", "tiff", "urdf", "webp", "xacro")
)
PACKAGE_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_-]*")
# a package not found makes ROS_PACKAGE_PATH be searched again, but not more often than this (s): each search took
# 5-15 ms of CPU, and a client asking for a new package name each time made one per fetchAsset
PACKAGE_SEARCH_S = 10.0
# bytes of files read kept for the next fetches (the most recently used): ten clients each fetching a 30 MB mesh
# four times at once read it forty times (+629 MB); kept, it is read once and its bytes shared by every answer
KEPT_BYTES = 64 * 1024 * 1024


class _Packages:
    """Package paths from one rospkg.RosPack, which searches ROS_PACKAGE_PATH once and remembers; a name it does
    not know makes a new one search again, at most every PACKAGE_SEARCH_S."""

    def __init__(self):
        self._lock = threading.Lock()
        self._rospack, self._searched = None, float("-inf")

    def path(self, package):
        with self._lock:
            found = self._find(package)
            if found is None and time.monotonic() - self._searched >= PACKAGE_SEARCH_S:
                self._rospack = None
                found = self._find(package)
        if found is None:
            raise RequestError(f"no ROS package {package!r}")
        return found

    def _find(self, package):
        if self._rospack is None:  # (a new one searches ROS_PACKAGE_PATH when first asked)
            self._rospack, self._searched = rospkg.RosPack(), time.monotonic()
        try:
            return os.path.realpath(self._rospack.get_path(package))
        except rospkg.ResourceNotFound:
            return None


class _Files:
    """The bytes of asset files: read one at a time (what is being read is one file at most), and kept while the
    file is the same (its inode, size and modification time), the most recently used up to KEPT_BYTES."""

    def __init__(self):
        self._lock = threading.Lock()
        self._kept = collections.OrderedDict()  # path -> ((inode, size, mtime), bytes)
        self._bytes = 0

    def read(self, path, uri):
        with self._lock, open(path, "rb", opener=lambda name, flags: os.open(name, flags | os.O_NONBLOCK)) as file:
            info = os.fstat(file.fileno())
            if not stat.S_ISREG(info.st_mode):  # (a FIFO would block the thread for good)
                raise RequestError(f"asset {uri[:80]!r}: not a regular file")
            if info.st_size > MAX_ASSET_BYTES:
                raise RequestError(f"asset {uri[:80]!r}: {info.st_size} bytes, over the bound of {MAX_ASSET_BYTES}")
            version = (info.st_ino, info.st_size, info.st_mtime_ns)
            kept = self._kept.pop(path, None)
            if kept is not None:
                self._bytes -= len(kept[1])
            data = kept[1] if kept is not None and kept[0] == version else file.read(MAX_ASSET_BYTES + 1)
            self._kept[path] = (version, data)
            self._bytes += len(data)
            while self._bytes > KEPT_BYTES:
                self._bytes -= len(self._kept.popitem(last=False)[1][1])
            return data


_packages, _files = _Packages(), _Files()


def asset_path(uri):
    """The file a package:// URI names, checked; RequestError saying why not."""
    if not isinstance(uri, str) or not uri.startswith("package://"):
        raise RequestError(f"asset {str(uri)[:80]!r}: only package:// URIs are served")
    package, _, relative = uri[len("package://") :].partition("/")
    relative = urllib.parse.unquote(relative)
    if not PACKAGE_NAME.fullmatch(package) or not relative:
        raise RequestError(f"asset {uri[:80]!r}: expected package://<package>/<path>")
    parts = relative.split("/")
    if any(part in ("", ".", "..") for part in parts) or "\x00" in relative:
        raise RequestError(f"asset {uri[:80]!r}: the path must not hold '..', '.' or empty parts")
    if relative.rpartition(".")[2].lower() not in EXTENSIONS:
        raise RequestError(
            f"asset {uri[:80]!r}: not a mesh, texture or robot description ({', '.join(sorted(EXTENSIONS))})"
        )
    root = _packages.path(package)
    path = os.path.realpath(os.path.join(root, *parts))
    if not path.startswith(root + os.sep):
        raise RequestError(f"asset {uri[:80]!r}: leads out of package {package}")
    return path


def read_asset(uri):
    """On a call thread: the bytes of the file uri names."""
    path = asset_path(uri)
    try:
        return _files.read(path, uri)
    except (FileNotFoundError, IsADirectoryError, NotADirectoryError):
        raise RequestError(f"asset {uri[:80]!r}: no such file") from None
    except OSError as error:
        raise RequestError(f"asset {uri[:80]!r}: {error.strerror}") from None
