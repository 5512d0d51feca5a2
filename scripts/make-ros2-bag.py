#!/usr/bin/env python3
"""Write a static IMU as a ROS 2 bag, with independent writers (not sagnac's):
mcap-ros2-support for a single MCAP file (profile ros2, CDR messages, ros2msg
schema), rosbags for a rosbag2 directory (MCAP or sqlite3 storage).

The samples: white noise on every axis (gyro in rad/s, accelerometer in m/s^2,
gravity on accel_z) from a seed, so a test knows them. --csv writes every
sample of the grid as CSV (gyro_x..accel_z, and `kept`: 0 for a sample left out
of the bag), for a test to compare the bag with the same numbers read as CSV.

Defects a bag meets on a robot: --holes I:N,... (N samples left out from grid
index I), --swaps K (K pairs of neighbours written out of order), --dups K
(K messages written twice), --jitter-ns J (stamp jitter, uniform +-J ns),
--second-topic (another Imu topic beside /imu), --dep-form short|long (the
schema names its dependencies `std_msgs/Header` or `std_msgs/msg/Header`).

Needs: numpy, mcap-ros2-support, rosbags (scripts/install-peers).
"""
import argparse
import csv
import shutil
from pathlib import Path

import numpy as np

IMU_FIELDS = """std_msgs/Header header
geometry_msgs/Quaternion orientation
float64[9] orientation_covariance
geometry_msgs/Vector3 angular_velocity
float64[9] angular_velocity_covariance
geometry_msgs/Vector3 linear_acceleration
float64[9] linear_acceleration_covariance
"""
DEPS = {
    "std_msgs/{}Header": "builtin_interfaces/Time stamp\nstring frame_id\n",
    "builtin_interfaces/{}Time": "int32 sec\nuint32 nanosec\n",
    "geometry_msgs/{}Quaternion": "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n",
    "geometry_msgs/{}Vector3": "float64 x\nfloat64 y\nfloat64 z\n",
}
AXES = ["gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"]
T0_NS = 1_700_000_000_000_000_000


def msgdef(long_form):
    """The Imu schema text; the MSG: lines name the dependencies pkg/Name or
    pkg/msg/Name (field types are always pkg/Name)."""
    mid = "msg/" if long_form else ""
    text = IMU_FIELDS
    for name, body in DEPS.items():
        text += "=" * 80 + "\nMSG: " + name.format(mid) + "\n" + body.replace("{}", "")
    return text


def samples(args):
    """Every sample of the grid, axis by axis."""
    rng = np.random.default_rng(args.seed)
    n = args.n
    fs = args.rate_hz
    # white rate noise of density d (unit/sqrt(Hz)): sample sigma d*sqrt(fs)
    gyro_d = np.array(args.gyro_density)
    accel_d = np.array(args.accel_density)
    out = {}
    for i, a in enumerate(AXES[:3]):
        out[a] = args.gyro_bias[i] + gyro_d[i] * np.sqrt(fs) * rng.standard_normal(n)
    for i, a in enumerate(AXES[3:]):
        g = 9.80665 if a == "accel_z" else 0.0
        out[a] = g + accel_d[i] * np.sqrt(fs) * rng.standard_normal(n)
    return out


def schedule(args, rng):
    """(grid index, stamp ns) of every message, in the order written."""
    keep = np.ones(args.n, dtype=bool)
    for h in args.holes:
        i, k = (int(v) for v in h.split(":"))
        keep[i:i + k] = False
    idx = np.flatnonzero(keep)
    period = 1e9 / args.rate_hz
    stamps = T0_NS + np.round(idx * period).astype(np.int64)
    if args.jitter_ns:
        stamps += rng.integers(-args.jitter_ns, args.jitter_ns + 1, len(idx))
    order = list(range(len(idx)))
    # swaps in the first half, duplicates in the second: each counts once
    half = len(idx) // 2
    for p in rng.choice(np.arange(10, half, 7), size=args.swaps, replace=False):
        order[p], order[p + 1] = order[p + 1], order[p]
    for p in sorted(rng.choice(np.arange(half, len(idx) - 10, 5), size=args.dups, replace=False),
                    reverse=True):
        order.insert(p + 1, order[p])
    return [(int(idx[o]), int(stamps[o])) for o in order], keep


def message(data, i, stamp):
    vec = lambda a, b, c: {"x": float(data[a][i]), "y": float(data[b][i]), "z": float(data[c][i])}
    return {
        "header": {"stamp": {"sec": stamp // 1_000_000_000, "nanosec": stamp % 1_000_000_000},
                   "frame_id": "imu_link"},
        "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0},
        "orientation_covariance": [-1.0] + [0.0] * 8,
        "angular_velocity": vec("gyro_x", "gyro_y", "gyro_z"),
        "angular_velocity_covariance": [0.0] * 9,
        "linear_acceleration": vec("accel_x", "accel_y", "accel_z"),
        "linear_acceleration_covariance": [0.0] * 9,
    }


def write_mcap(path, msgs, data, args):
    from mcap.writer import CompressionType
    from mcap_ros2.writer import Writer
    comp = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4,
            "none": CompressionType.NONE}[args.compression]
    with open(path, "wb") as f:
        w = Writer(f, chunk_size=64 * 1024, compression=comp)
        schema = w.register_msgdef("sensor_msgs/msg/Imu", msgdef(args.dep_form == "long"))
        for seq, (i, stamp) in enumerate(msgs):
            # log time: when the recorder received it (later than the stamp, and in file order)
            w.write_message("/imu", schema, message(data, i, stamp),
                            log_time=T0_NS + 2_000_000 + seq * 1000, sequence=seq)
            if args.second_topic:
                w.write_message("/imu/filtered", schema, message(data, i, stamp),
                                log_time=T0_NS + 2_000_000 + seq * 1000, sequence=seq)
        w.finish()


def write_rosbag2(path, msgs, data, args, storage, seq0=0):
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.rosbag2.enums import CompressionFormat, CompressionMode
    from rosbags.typesys import Stores, get_typestore
    ts = get_typestore(Stores.ROS2_HUMBLE)
    Imu = ts.types["sensor_msgs/msg/Imu"]
    Header = ts.types["std_msgs/msg/Header"]
    Time = ts.types["builtin_interfaces/msg/Time"]
    Quat = ts.types["geometry_msgs/msg/Quaternion"]
    Vec3 = ts.types["geometry_msgs/msg/Vector3"]
    plugin = {"mcap": StoragePlugin.MCAP, "sqlite3": StoragePlugin.SQLITE3}[storage]
    w = Writer(path, version=9, storage_plugin=plugin)
    if args.kind == "dir-zstd":
        # rosbag2's file compression: each file zstd-compressed whole
        w.set_compression(CompressionMode.FILE, CompressionFormat.ZSTD)
    with w:
        conn = w.add_connection("/imu", Imu.__msgtype__, typestore=ts)
        for seq, (i, stamp) in enumerate(msgs, start=seq0):
            v = lambda a, b, c: Vec3(x=float(data[a][i]), y=float(data[b][i]), z=float(data[c][i]))
            m = Imu(header=Header(stamp=Time(sec=stamp // 10**9, nanosec=stamp % 10**9),
                                  frame_id="imu_link"),
                    orientation=Quat(x=0.0, y=0.0, z=0.0, w=1.0),
                    orientation_covariance=np.array([-1.0] + [0.0] * 8),
                    angular_velocity=v("gyro_x", "gyro_y", "gyro_z"),
                    angular_velocity_covariance=np.zeros(9),
                    linear_acceleration=v("accel_x", "accel_y", "accel_z"),
                    linear_acceleration_covariance=np.zeros(9))
            w.write(conn, T0_NS + 2_000_000 + seq * 1000, ts.serialize_cdr(m, Imu.__msgtype__))


def write_split(path, msgs, data, args):
    """A rosbag2 directory of two MCAP files (the recorder split it)."""
    from io import StringIO
    from ruamel.yaml import YAML
    yaml = YAML(typ="safe")
    yaml.default_flow_style = False
    half = len(msgs) // 2
    parts = [msgs[:half], msgs[half:]]
    tmp = [Path(str(path) + f".part{k}") for k in range(2)]
    for t, part, seq0 in zip(tmp, parts, [0, half]):
        write_rosbag2(t, part, data, args, "mcap", seq0)
    path.mkdir()
    files = []
    for k, t in enumerate(tmp):
        f = next(t.glob("*.mcap"))
        name = f"{path.name}_{k}.mcap"
        shutil.move(f, path / name)
        files.append(name)
    meta = yaml.load((tmp[0] / "metadata.yaml").read_text())
    info = meta["rosbag2_bagfile_information"]
    info["relative_file_paths"] = files
    info["files"] = [{"path": f} for f in files]
    text = StringIO()
    yaml.dump(meta, text)
    (path / "metadata.yaml").write_text(text.getvalue())
    for t in tmp:
        shutil.rmtree(t)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--out", required=True, type=Path)
    p.add_argument("--kind", choices=["mcap", "dir", "dir-zstd", "split", "sqlite"], default="mcap")
    p.add_argument("--rate-hz", type=float, default=200.0)
    p.add_argument("--n", type=int, default=20000)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--gyro-density", type=float, nargs=3, default=[1e-4, 2e-4, 3e-4],
                   help="rad/s/sqrt(Hz), per axis")
    p.add_argument("--gyro-bias", type=float, nargs=3, default=[1e-3, -2e-3, 5e-4])
    p.add_argument("--accel-density", type=float, nargs=3, default=[1e-3, 2e-3, 3e-3],
                   help="m/s^2/sqrt(Hz), per axis")
    p.add_argument("--compression", choices=["zstd", "lz4", "none"], default="zstd")
    p.add_argument("--holes", nargs="*", default=[])
    p.add_argument("--swaps", type=int, default=0)
    p.add_argument("--dups", type=int, default=0)
    p.add_argument("--jitter-ns", type=int, default=0)
    p.add_argument("--second-topic", action="store_true")
    p.add_argument("--dep-form", choices=["short", "long"], default="short")
    p.add_argument("--nan-at", type=int, help="gyro_y of this grid index is NaN (a broken message)")
    p.add_argument("--csv", type=Path)
    args = p.parse_args()
    data = samples(args)
    if args.nan_at is not None:
        data["gyro_y"][args.nan_at] = float("nan")
    msgs, keep = schedule(args, np.random.default_rng(args.seed + 1))
    if args.kind == "mcap":
        write_mcap(args.out, msgs, data, args)
    elif args.kind == "split":
        write_split(args.out, msgs, data, args)
    else:
        write_rosbag2(args.out, msgs, data, args, "sqlite3" if args.kind == "sqlite" else "mcap")
    if args.csv:
        with open(args.csv, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(AXES + ["kept"])
            for i in range(args.n):
                w.writerow([repr(float(data[a][i])) for a in AXES] + [int(keep[i])])


if __name__ == "__main__":
    main()
