"""Writes meshes/turtle_shell.stl, the demo turtle's shell for 3D viewers (urdf/turtle.urdf names it): a dome, an
ellipsoid's upper half, 0.5 m long, 0.4 m wide and 0.15 m high, as a binary STL. Run once; its output is committed.
    /usr/bin/python3 tools/make_turtle_mesh.py"""

import math
import struct
from pathlib import Path

LENGTH, WIDTH, HEIGHT = 0.5, 0.4, 0.15
SEGMENTS, RINGS = 24, 8


def point(ring, segment):
    """The dome's point at latitude ring/RINGS (0: the rim) and longitude segment/SEGMENTS."""
    latitude = math.pi / 2 * ring / RINGS
    longitude = 2 * math.pi * segment / SEGMENTS
    return (
        LENGTH / 2 * math.cos(latitude) * math.cos(longitude),
        WIDTH / 2 * math.cos(latitude) * math.sin(longitude),
        HEIGHT * math.sin(latitude),
    )


def triangles():
    for ring in range(RINGS):
        for segment in range(SEGMENTS):
            a, b = point(ring, segment), point(ring, segment + 1)
            c, d = point(ring + 1, segment), point(ring + 1, segment + 1)
            yield a, b, d
            if ring + 1 < RINGS:  # (the top ring's upper edge is one point)
                yield a, d, c
    rim_centre = (0.0, 0.0, 0.0)
    for segment in range(SEGMENTS):  # the flat underside
        yield rim_centre, point(0, segment + 1), point(0, segment)


def normal(a, b, c):
    u = [b[i] - a[i] for i in range(3)]
    v = [c[i] - a[i] for i in range(3)]
    n = (u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0])
    length = math.sqrt(sum(x * x for x in n)) or 1.0
    return tuple(x / length for x in n)


def main():
    faces = list(triangles())
    data = bytearray(b"turtlesim demo turtle shell".ljust(80, b" "))
    data += struct.pack("<I", len(faces))
    for a, b, c in faces:
        data += struct.pack("<12fH", *normal(a, b, c), *a, *b, *c, 0)
    Path(__file__).resolve().parent.parent.joinpath("meshes", "turtle_shell.stl").write_bytes(data)


if __name__ == "__main__":
    main()
