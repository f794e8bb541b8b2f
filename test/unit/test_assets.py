"""ros_side.assets: what fetchAsset may read (a package's own files, of the kinds a viewer draws), with a package
of a temporary folder; and what repeated fetches cost (packages searched for, files read)."""

import os

import pytest
import rospkg

from rosbridge.errors import RequestError
from rosbridge.ros_side import assets


class RosPack:
    """rospkg.RosPack over one package, `pkg` in `root`; counts the searches (one per RosPack made)."""

    made = 0

    def __init__(self):
        RosPack.made += 1

    def get_path(self, package):
        if package != "pkg":
            raise rospkg.ResourceNotFound(package)
        return str(RosPack.root)


@pytest.fixture
def package(tmp_path, monkeypatch):
    root = tmp_path / "pkg"
    (root / "meshes").mkdir(parents=True)
    (root / "meshes" / "a.stl").write_bytes(b"mesh")
    RosPack.root, RosPack.made = root, 0
    monkeypatch.setattr(assets.rospkg, "RosPack", RosPack)
    monkeypatch.setattr(assets, "_packages", assets._Packages())
    monkeypatch.setattr(assets, "_files", assets._Files())
    return root


@pytest.mark.parametrize(
    "uri, words",
    [
        ("package://pkg/../pkg/meshes/a.stl", "'..'"),
        ("package://pkg/meshes/%2e%2e/%2e%2e/etc/passwd.stl", "'..'"),
        ("package://pkg/meshes/./a.stl", "'..'"),
        ("package://pkg/meshes//a.stl", "'..'"),
        ("package://pkg/meshes/a.stl%00.png", "'..'"),
        ("package://pkg/meshes/outside.stl", "leads out of package pkg"),
        ("package://pkg/meshes/fifo.stl", "not a regular file"),
        ("package://pkg/meshes/folder.stl", "no such file"),
        ("package://pkg/meshes/" + "x" * 5000 + ".stl", "File name too long"),
        ("package://pkg/meshes/a.txt", "not a mesh"),
        ("package://../meshes/a.stl", "expected package://"),
        ("package://nope/meshes/a.stl", "no ROS package 'nope'"),
        ("file:///etc/passwd", "only package://"),
        ("package://pkg/proc.stl", "leads out of package pkg"),
    ],
)
def test_only_the_package_s_own_regular_files_are_read(package, tmp_path, uri, words):
    (tmp_path / "secret.stl").write_bytes(b"secret")
    (package / "meshes" / "outside.stl").symlink_to(tmp_path / "secret.stl")
    (package / "proc.stl").symlink_to("/proc/self/environ")
    os.mkfifo(package / "meshes" / "fifo.stl")  # (a read would wait for a writer for good)
    (package / "meshes" / "folder.stl").mkdir()
    with pytest.raises(RequestError, match=words):
        assets.read_asset(uri)
    assert assets.read_asset("package://pkg/meshes/a.stl") == b"mesh"


def test_a_package_not_found_is_searched_for_again_at_most_every_package_search_s(package, monkeypatch):
    """Before, each fetch of a package not found searched ROS_PACKAGE_PATH anew (5-15 ms of CPU each)."""
    now = [1000.0]
    monkeypatch.setattr(assets.time, "monotonic", lambda: now[0])
    for n in range(100):
        with pytest.raises(RequestError, match="no ROS package"):
            assets.read_asset(f"package://nope{n}/a.stl")
    assert RosPack.made == 1
    now[0] += assets.PACKAGE_SEARCH_S
    with pytest.raises(RequestError):
        assets.read_asset("package://nope/a.stl")
    assert RosPack.made == 2
    assert assets.read_asset("package://pkg/meshes/a.stl") == b"mesh" and RosPack.made == 2


def test_a_file_fetched_again_is_not_read_again_while_it_is_the_same(package, monkeypatch):
    """Every answer shares the bytes read once. Before, ten clients fetching a 30 MB mesh four times at once
    read it forty times (+629 MB)."""
    first = assets.read_asset("package://pkg/meshes/a.stl")
    assert assets.read_asset("package://pkg/meshes/a.stl") is first
    (package / "meshes" / "a.stl").write_bytes(b"new mesh")
    assert assets.read_asset("package://pkg/meshes/a.stl") == b"new mesh"
    monkeypatch.setattr(assets, "KEPT_BYTES", 10)  # (what is kept stays within its bound)
    (package / "meshes" / "b.stl").write_bytes(b"other")
    assets.read_asset("package://pkg/meshes/b.stl")
    assert assets._files._bytes == len(b"other")
