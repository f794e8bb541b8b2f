"""Assets for Foxglove clients (fetchAsset): files of ROS packages named by `package://` URIs, as a robot
description names its meshes. Only a package's own files (no `..`, no symlink out of it), of the kinds a viewer
draws, within a size bound. Read on a call thread (services.ServiceCalls.run)."""

import functools
import os
import re
import stat
import urllib.parse

import rospkg

from rosbridge.errors import RequestError

MAX_ASSET_BYTES = 32 * 1024 * 1024
# meshes, textures and robot descriptions (foxglove_bridge's default allowlist names the same kinds)
EXTENSIONS = frozenset(
    ("dae", "fbx", "glb", "gltf", "jpeg", "jpg", "mtl", "obj", "png", "stl", "tif", "tiff", "urdf", "webp", "xacro")
)
PACKAGE_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_-]*")


@functools.lru_cache(maxsize=256)
def _package_path(package):
    try:
        return os.path.realpath(rospkg.RosPack().get_path(package))
    except rospkg.ResourceNotFound:
        raise RequestError(f"no ROS package {package!r}") from None


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
    root = _package_path(package)
    path = os.path.realpath(os.path.join(root, *parts))
    if not path.startswith(root + os.sep):
        raise RequestError(f"asset {uri[:80]!r}: leads out of package {package}")
    return path


def read_asset(uri):
    """On a call thread: the bytes of the file uri names."""
    path = asset_path(uri)
    try:
        with open(path, "rb", opener=lambda name, flags: os.open(name, flags | os.O_NONBLOCK)) as file:
            info = os.fstat(file.fileno())
            if not stat.S_ISREG(info.st_mode):  # (a FIFO would block the thread for good)
                raise RequestError(f"asset {uri[:80]!r}: not a regular file")
            size = info.st_size
            if size > MAX_ASSET_BYTES:
                raise RequestError(f"asset {uri[:80]!r}: {size} bytes, over the bound of {MAX_ASSET_BYTES}")
            return file.read(MAX_ASSET_BYTES + 1)
    except (FileNotFoundError, IsADirectoryError, NotADirectoryError):
        raise RequestError(f"asset {uri[:80]!r}: no such file") from None
    except OSError as error:
        raise RequestError(f"asset {uri[:80]!r}: {error.strerror}") from None
