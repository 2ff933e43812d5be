#!/usr/bin/env python3
"""voxfield.dask on a Zarr volume on a two-worker distributed.LocalCluster, against the
one-piece module on the same machine.

Usage (module built into build/python, or installed by pip):
    PYTHONPATH=build/python VOXFIELD_DEVICE=cpu python3 bench/dask_zarr.py --size 512 \
        --block 128 --json bench/results/pocl-dask-zarr-512.json

Writes the floor + spheres world (bench/worlds.py; N^3 uint8, seeded) to a Zarr volume of
--block^3 chunks in --dir, then for the bounded field (euclidean, --max-distance D, f32) and
the unbounded one (euclidean f32): the wall time of reading the Zarr volume, computing on the
cluster (--workers single-threaded worker processes, each with $VOXFIELD_DEVICE) and writing
the field to Zarr; the peak resident memory of each worker (ru_maxrss; workers restarted
between runs); the one-piece voxfield.distance_transform of the whole array in this process
(wall time, array already in memory); and whether the two are equal.
"""

import argparse
import datetime
import json
import os
import resource
import shutil
import subprocess
import sys
import time

import dask.array as da
import distributed
import numpy as np
import zarr

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from worlds import make_world  # noqa: E402

import voxfield  # noqa: E402
import voxfield.dask as vd  # noqa: E402

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def peak_rss_bytes():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def commit():
    try:
        return subprocess.run(["git", "-C", REPO, "rev-parse", "HEAD"], capture_output=True,
                              text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--size", type=int, default=512)
    p.add_argument("--block", type=int, default=128)
    p.add_argument("--max-distance", type=float, default=16)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--dir", default="/tmp/voxfield-dask-bench")
    p.add_argument("--json", default="")
    args = p.parse_args()
    n, b = args.size, args.block
    shutil.rmtree(args.dir, ignore_errors=True)
    os.makedirs(args.dir)
    src = os.path.join(args.dir, "world.zarr")
    world = make_world(n, 1)
    zarr.array(world, chunks=(b, b, b), store=src, overwrite=True)
    device = os.environ.get("VOXFIELD_DEVICE", "")
    rows = []
    with distributed.LocalCluster(n_workers=args.workers, threads_per_worker=1,
                                  dashboard_address=None, silence_logs=40) as cluster, \
            distributed.Client(cluster) as client:
        for name, bound in (("bounded", args.max_distance), ("unbounded", None)):
            client.restart()
            if device:
                client.run(lambda: os.environ.__setitem__("VOXFIELD_DEVICE", device))
            out = os.path.join(args.dir, f"{name}.zarr")
            t = time.perf_counter()
            field = vd.distance_transform(da.from_zarr(src), metric="euclidean",
                                          max_distance=bound)
            da.to_zarr(field, out, overwrite=True)
            wall = time.perf_counter() - t
            peaks = list(client.run(peak_rss_bytes).values())
            t = time.perf_counter()
            one = voxfield.distance_transform(world, metric="euclidean", max_distance=bound)
            one_wall = time.perf_counter() - t
            equal = bool(np.array_equal(zarr.open(out)[...], one))
            rows.append({"field": name, "max_distance": bound, "dask_wall_s": wall,
                         "one_piece_wall_s": one_wall, "ratio": wall / one_wall,
                         "worker_peak_rss_bytes": peaks, "equal": equal})
            print(f"{name:9s} dask {wall:7.2f} s  one piece {one_wall:6.2f} s  "
                  f"x{wall / one_wall:.2f}  worker peaks "
                  f"{[round(x / 2**30, 2) for x in peaks]} GiB  equal {equal}")
            del one
    devs = voxfield.devices()
    dev = next((d for d in devs if str(d["index"]) == device or d["type"] == device), devs[0])
    result = {"device": dev, "date": datetime.datetime.now(datetime.timezone.utc).isoformat(),
              "commit": commit(), "size": [n, n, n], "block": [b, b, b], "dtype": "uint8",
              "workers": args.workers, "threads_per_worker": 1, "cpus": os.cpu_count(),
              "results": rows}
    if args.json:
        with open(args.json, "w") as f:
            json.dump(result, f, indent=1)
    shutil.rmtree(args.dir, ignore_errors=True)


if __name__ == "__main__":
    main()
