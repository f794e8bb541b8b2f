"""Micro-benchmark of the ROS <-> JSON conversion, in microseconds per call: the bridge's direct roads
(rosbridge.codec.ros_to_json: ROS bytes -> JSON text; codec.json_to_ros: parsed JSON -> ROS bytes;
codec.ros_to_cbor: ROS bytes -> CBOR) beside the genpy roads (deserialize + convert.to_json + dumps; convert.from_json
+ serialize), and the other wire encodings (best of several repeats, so a busy machine disturbs it less).

Then the big messages a rover publishes (a 4000x4000 nav_msgs/OccupancyGrid, a 300k-point sensor_msgs/PointCloud2),
each encoded into the frame the bridge sends (as frames.TopicMessage does), as JSON and as CBOR, by each road: `now`
(the direct roads), `genpy` (the message deserialized by genpy, then to_json + dumps, or to_cbor_value: the road the
bridge took for CBOR before ros_to_cbor) and, with --before REV, the direct roads of that git revision. Each road
runs in a process of its own, encoding the message --reps times (the genpy road's JSON, a second a map, at most 3),
a cloud and a laser scan encoded the same way between two. The table gives the CPU of the 1st and the last, and
per MB of ROS bytes; the process's peak RSS above what it held before (VmHWM, reset before each), at the 1st and
the last; what it still holds after the last (all medians over --rounds runs). No roscore needed:

    export PATH=/usr/bin:$PATH; source .build/setup.bash; python3 bench/convert_bench.py [--before REV]
"""

import argparse
import ctypes
import gc
import itertools
import json
import os
import statistics
import subprocess
import sys
import time
import timeit
import types

import geometry_msgs.msg
import nav_msgs.msg
import sensor_msgs.msg
from nav_messages import deserialized, laser_scan, occupancy_grid, point_cloud, serialized

from rosbridge.codec.cbor import cbor_parts, to_cbor_value
from rosbridge.codec.json_to_ros import packer
from rosbridge.codec.json_values import dumps, from_json, to_json
from rosbridge.codec.ros_to_cbor import cbor_value
from rosbridge.codec.ros_to_json import SPLICE_MARK, json_parts, json_text
from rosbridge.codec.wrapping import png_frame
from rosbridge.protocol.encoded import Utf8Text, cbor_frame

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TOPIC = "/bench"


def best_microseconds(function, repeats=5):
    timer = timeit.Timer(function)
    number, _ = timer.autorange()  # enough calls for about 0.2 s
    return min(timer.repeat(repeats, number)) / number * 1e6


def samples():
    twist = geometry_msgs.msg.Twist()
    twist.linear.x, twist.angular.z = 1.5, -0.25
    image = sensor_msgs.msg.Image(
        height=480, width=640, encoding="rgb8", step=640 * 3, data=bytes(range(256)) * (640 * 480 * 3 // 256)
    )
    image.header.frame_id = "camera"
    return {
        "geometry_msgs/Twist": twist,
        "sensor_msgs/LaserScan 1081 rays": deserialized(sensor_msgs.msg.LaserScan, serialized(laser_scan())),
        "sensor_msgs/Image 640x480 rgb8": image,
    }


def micro_table():
    print(f"{'message':34} {'operation':36} {'us/call':>10}")
    for name, msg in samples().items():
        value = to_json(msg)
        parsed = json.loads(dumps(value))
        cls, data = type(msg), serialized(msg)
        cases = {
            "bytes -> text: genpy, to_json, dumps": lambda: dumps(to_json(deserialized(cls, data))),
            "bytes -> text: wire.json_text": lambda: json_text(cls)(data),
            "bytes -> cbor: genpy, to_cbor_value": lambda: cbor_frame(to_cbor_value(deserialized(cls, data))),
            "bytes -> cbor: ros_to_cbor": lambda: cbor_frame(cbor_value(cls)(data)),
            "parsed -> bytes: from_json, genpy": lambda: serialized(from_json(cls, parsed)),
            "parsed -> bytes: packing.packer": lambda: packer(cls)(parsed),
            "to_json": lambda: to_json(msg),
            "from_json": lambda: from_json(type(msg), parsed),
            "dumps(to_json)": lambda: dumps(to_json(msg)),
            "from_json(json.loads(text))": lambda text=dumps(value): from_json(type(msg), json.loads(text)),
            "cbor_frame(to_cbor_value)": lambda: cbor_frame(to_cbor_value(msg)),
            "png_frame(dumps(to_json))": lambda: png_frame(dumps(to_json(msg))),
        }
        for operation, function in cases.items():
            print(f"{name:34} {operation:36} {best_microseconds(function):10.2f}")


# ---------------------------------------------------------------------------------------------------------
# Big messages

BIG = {
    "nav_msgs/OccupancyGrid 4000x4000": lambda: (nav_msgs.msg.OccupancyGrid, serialized(occupancy_grid())),
    "sensor_msgs/PointCloud2 300k points": lambda: (sensor_msgs.msg.PointCloud2, serialized(point_cloud())),
}


def module_at(revision, path, name):
    """The module at `path` as it was at git `revision` (its imports from the rosbridge package of today)."""
    source = subprocess.run(
        ["git", "-C", REPO, "show", f"{revision}:{path}"], capture_output=True, text=True, check=True
    ).stdout
    module = types.ModuleType(name)
    module.__file__ = f"{revision}:{path}"
    sys.modules[name] = module
    exec(compile(source, module.__file__, "exec"), module.__dict__)
    return module


def json_publish(text, spliced):
    """The frame of a publish op as frames.TopicMessage makes it: its parts (the big ones by reference)."""
    text = '{"op":"publish","topic":%s,"msg":%s}' % (dumps(TOPIC), text)
    if spliced:
        pieces = text.encode().split(SPLICE_MARK.encode())
        return [*itertools.chain.from_iterable(zip(pieces, spliced)), pieces[-1]]
    return [Utf8Text(text.encode())]


def encoder(road, encoding, before=None):
    """road, encoding -> a function (cls, data) -> the frame's parts."""
    if road == "now" and encoding == "json":
        return lambda cls, data: json_publish(*json_parts(cls)(data))
    if road == "now":
        return lambda cls, data: cbor_parts({"op": "publish", "topic": TOPIC, "msg": cbor_value(cls)(data)})
    if road == "genpy" and encoding == "json":
        return lambda cls, data: json_publish(dumps(to_json(deserialized(cls, data))), [])
    if road == "genpy":
        return lambda cls, data: cbor_parts(
            {"op": "publish", "topic": TOPIC, "msg": to_cbor_value(deserialized(cls, data))}
        )
    if encoding == "json":  # before: REV's ros_to_json
        old = module_at(before, "src/rosbridge/codec/ros_to_json.py", "ros_to_json_before")
        return lambda cls, data: json_publish(*old.json_parts(cls)(data))
    # before, CBOR: REV's cbor.to_cbor_value of genpy's message if REV has no ros_to_cbor, else its ros_to_cbor
    try:
        old = module_at(before, "src/rosbridge/codec/ros_to_cbor.py", "ros_to_cbor_before")
        return lambda cls, data: cbor_parts({"op": "publish", "topic": TOPIC, "msg": old.cbor_value(cls)(data)})
    except subprocess.CalledProcessError:
        old_cbor = module_at(before, "src/rosbridge/codec/cbor.py", "cbor_before")
        return lambda cls, data: old_cbor.cbor_parts(
            {"op": "publish", "topic": TOPIC, "msg": old_cbor.to_cbor_value(deserialized(cls, data))}
        )


def _status_kb(*keys):
    with open("/proc/self/status") as status:
        found = {line.split(":")[0]: int(line.split()[1]) for line in status if line.startswith(keys)}
    return [found[key] for key in keys]


def _trim():
    """glibc gives the free memory at the top of its heap back (the idle figure is then what is really in use)."""
    try:
        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):
        pass


def _reset_peak():
    with open("/proc/self/clear_refs", "w") as refs:  # (Linux: VmHWM starts again from VmRSS)
        refs.write("5")


def one_road(name, road, encoding, reps, before):
    """In a process of its own: reps encodings of the big message `name`, a cloud and a scan between two; prints
    JSON: [[cpu s, peak kB above idle, kB held after], ...], the frame's size."""
    cls, data = BIG[name]()
    others = [BIG["sensor_msgs/PointCloud2 300k points"](), (sensor_msgs.msg.LaserScan, serialized(laser_scan()))]
    encode = encoder(road, encoding, before)
    encode(cls, serialized(cls()))  # (readers generated, modules imported: not counted)
    for other_cls, other in others:
        encode(other_cls, other)
    gc.collect()
    results = []
    for _ in range(reps):
        gc.collect()
        _trim()
        (idle,) = _status_kb("VmRSS")
        _reset_peak()
        started = time.process_time()
        parts = encode(cls, data)
        cpu = time.process_time() - started
        (peak,) = _status_kb("VmHWM")
        size = sum(map(len, parts))
        del parts
        gc.collect()
        (after,) = _status_kb("VmRSS")  # (not trimmed: what the process keeps)
        results.append([cpu, peak - idle, after - idle])
        for other_cls, other in others:
            encode(other_cls, other)
    print(json.dumps({"results": results, "size": size, "bytes": len(data)}))


def big_table(roads, reps, rounds, before):
    runs = {}
    for _ in range(rounds):  # (rounds alternate the roads, so a busy moment hits them alike)
        for name, encoding, road in itertools.product(BIG, ("json", "cbor"), roads):
            reps_here = reps if road != "genpy" or encoding == "cbor" else min(reps, 3)  # (3 s a map each)
            command = [
                sys.executable,
                os.path.abspath(__file__),
                "--one",
                name,
                road,
                encoding,
                "--reps",
                str(reps_here),
            ] + (["--before", before] if before else [])
            out = subprocess.run(command, capture_output=True, text=True, check=True).stdout
            runs.setdefault((name, encoding, road), []).append(json.loads(out))
    label = {"now": "now", "genpy": "genpy", "before": f"before ({before})"}
    print(
        f"\n{'big message':36} {'road':22} {'CPU ms: 1st / last':>19} {'ms/MB':>7} "
        f"{'peak MB: 1st / last':>20} {'held MB':>8} {'frame MB':>9}"
    )
    for (name, encoding, road), results in runs.items():

        def median(index, rep):
            return statistics.median(run["results"][rep][index] for run in results)

        cpu = statistics.median(statistics.median(rep[0] for rep in run["results"]) for run in results)
        road_name = f"{encoding.upper()}: {label[road]}"
        print(
            f"{name:36} {road_name:22} {median(0, 0) * 1e3:9.1f} / {median(0, -1) * 1e3:7.1f} "
            f"{cpu / results[0]['bytes'] * 1e9:7.2f} {median(1, 0) / 1024:9.0f} / {median(1, -1) / 1024:8.0f} "
            f"{median(2, -1) / 1024:8.1f} {results[0]['size'] / 1e6:9.1f}"
        )


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--before", metavar="REV", help="also the direct roads of this git revision (e.g. HEAD~3)")
    p.add_argument("--reps", type=int, default=10, help="encodings of each big message per process")
    p.add_argument("--rounds", type=int, default=1, help="processes per road (the table shows medians)")
    p.add_argument("--big-only", action="store_true", help="only the big messages")
    p.add_argument("--one", nargs=3, metavar=("MESSAGE", "ROAD", "ENCODING"), help=argparse.SUPPRESS)
    a = p.parse_args()
    if a.one:
        one_road(*a.one, a.reps, a.before)
        return
    if not a.big_only:
        micro_table()
    roads = ["genpy"] + (["before"] if a.before else []) + ["now"]
    big_table(roads, a.reps, a.rounds, a.before)


if __name__ == "__main__":
    main()
