#!/usr/bin/env python3
"""voxfield.dask on a Zarr volume on a two-worker distributed.LocalCluster, against the
one-piece module on the same machine.

Usage (module built into build/python, or installed by pip):
    PYTHONPATH=build/python VOXFIELD_DEVICE=cpu nice -n 19 python3 bench/dask_zarr.py \
        --size 1024 --block 128 --json bench/results/pocl-dask-zarr-1024.json

Writes the floor + spheres world (bench/worlds.py; N^3 uint8, seeded) to a Zarr volume of
--block^3 chunks in --dir, then for the bounded field (euclidean, --max-distance D, f32), the
unbounded one (euclidean f32), and the drop-ins `edt` (distance_transform_edt of world == 0,
float64) and `cdt` (distance_transform_cdt of world == 0, taxicab, int32): the wall time of reading the Zarr volume, computing on the
cluster (--workers single-threaded worker processes, each with $VOXFIELD_DEVICE and
--memory-limit, past which distributed spills to --dir) and writing the field to Zarr; the
peak resident memory of each worker (VmHWM, workers restarted between runs) and the CPU time
each used; the one-piece voxfield.distance_transform of the whole array in this process (wall
and CPU time, array already in memory, its kernels built first on one block); and whether
the two are equal, compared slab by slab (one block thick) so that the Dask field is never
read whole. --fields picks the runs. The workers' CPU time is also split by task prefix
(each task's thread CPU time, summed over both workers; "outside tasks": the rest of the
workers' CPU during the run: transfers, serialization, the event loop). The JSON also records the device, the date, the commit,
the load average before and after each run and this process's peak memory. CPU times say
what the load average hides: on a shared machine the wall times follow the other work.
"""

import argparse
import datetime
import json
import os
import resource
import shutil
import sys
import time

import dask.array as da
import distributed
import numpy as np
import zarr

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from repo import git_commit  # noqa: E402
from worlds import make_world  # noqa: E402

import voxfield  # noqa: E402
import voxfield.dask as vd  # noqa: E402
from voxfield import ndimage  # noqa: E402


def peak_rss_bytes():
    """This process's peak resident memory: VmHWM, the high-water mark of its own address
    space. (ru_maxrss is not used: Linux carries the parent's high-water mark into a child
    across exec, so a worker spawned by a big parent reports the parent's peak.)"""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def cpu_seconds():
    """CPU time (user + system, all threads) this process has used."""
    return time.process_time()


def rusage_peak_bytes():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def count_task_cpu():
    """In a worker: from now on add each task's thread CPU time to a total per task prefix
    (distributed.worker.apply_function wrapped); returns the process CPU time so far."""
    import collections

    import distributed.worker as worker
    from dask.utils import key_split

    worker.voxfield_task_cpu = collections.defaultdict(float)
    run = getattr(worker.apply_function, "voxfield_wrapped", worker.apply_function)

    def counted(function, args, kwargs, execution_state, key, *rest, **kw):
        start = time.thread_time()
        try:
            return run(function, args, kwargs, execution_state, key, *rest, **kw)
        finally:
            worker.voxfield_task_cpu[key_split(key)] += time.thread_time() - start

    counted.voxfield_wrapped = run
    worker.apply_function = counted
    return time.process_time()


def task_cpu():
    """In a worker: the task CPU totals count_task_cpu started, and the process CPU time."""
    import distributed.worker as worker
    return dict(worker.voxfield_task_cpu), time.process_time()


def equal_by_slabs(path, want, depth):
    """Whether the Zarr array at `path` equals `want`, read `depth` planes at a time."""
    got = zarr.open(path, mode="r")
    if got.shape != want.shape or got.dtype != want.dtype:
        return False
    return all(np.array_equal(got[z:z + depth], want[z:z + depth])
               for z in range(0, want.shape[0], depth))


def dask_field(name, world, bound):
    """The lazy field of run `name` of a dask world."""
    if name == "edt":
        return vd.distance_transform_edt(world == 0)
    if name == "cdt":
        return vd.distance_transform_cdt(world == 0, metric="taxicab")
    return vd.distance_transform(world, metric="euclidean", max_distance=bound)


def one_piece(name, world, bound):
    """The same field of a numpy world by the one-piece module."""
    if name == "edt":
        return ndimage.distance_transform_edt(world == 0)
    if name == "cdt":
        return ndimage.distance_transform_cdt(world == 0, metric="taxicab")
    return voxfield.distance_transform(world, metric="euclidean", max_distance=bound)


def load():
    return [round(x, 2) for x in os.getloadavg()]


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--size", type=int, default=512)
    p.add_argument("--block", type=int, default=128)
    p.add_argument("--max-distance", type=float, default=16)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--memory-limit", default="2GiB",
                   help="each worker's memory_limit (distributed spills to disk past 60%%)")
    p.add_argument("--dir", default="/tmp/voxfield-dask-bench")
    p.add_argument("--fields", default="bounded,unbounded",
                   help="which fields to run, comma-separated (bounded, unbounded, edt, cdt)")
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
                                  memory_limit=args.memory_limit,
                                  local_directory=os.path.join(args.dir, "workers"),
                                  dashboard_address=None, silence_logs=40) as cluster, \
            distributed.Client(cluster) as client:
        bound_of = {"bounded": args.max_distance, "unbounded": None, "edt": None, "cdt": None}
        for name in args.fields.split(","):
            bound = bound_of[name]
            client.restart()
            if device:
                client.run(lambda: os.environ.__setitem__("VOXFIELD_DEVICE", device))
            out = os.path.join(args.dir, f"{name}.zarr")
            cpu_at_start = client.run(count_task_cpu)
            load_before = load()
            t = time.perf_counter()
            field = dask_field(name, da.from_zarr(src), bound)
            da.to_zarr(field, out, overwrite=True)
            wall = time.perf_counter() - t
            peaks = list(client.run(peak_rss_bytes).values())
            worker_cpu = list(client.run(cpu_seconds).values())
            rusage_peaks = list(client.run(rusage_peak_bytes).values())
            by_task, during = {}, 0.0
            for address, (totals, cpu_now) in client.run(task_cpu).items():
                during += cpu_now - cpu_at_start[address]
                for prefix, seconds in totals.items():
                    by_task[prefix] = by_task.get(prefix, 0.0) + seconds
            by_task = dict(sorted(by_task.items(), key=lambda kv: -kv[1]))
            by_task["outside tasks"] = during - sum(by_task.values())
            load_between = load()
            # Kernels built before the clock starts (PoCL builds a kernel per process).
            one_piece(name, world[:b, :b, :b], bound)
            t, cpu = time.perf_counter(), time.process_time()
            one = one_piece(name, world, bound)
            one_wall, one_cpu = time.perf_counter() - t, time.process_time() - cpu
            equal = equal_by_slabs(out, one, b)
            rows.append({"field": name, "max_distance": bound, "dask_wall_s": wall,
                         "one_piece_wall_s": one_wall, "ratio": wall / one_wall,
                         "worker_cpu_s": worker_cpu, "one_piece_cpu_s": one_cpu,
                         "worker_peak_rss_bytes": peaks,
                         "worker_ru_maxrss_bytes": rusage_peaks,
                         "worker_cpu_during_run_s": during, "worker_cpu_by_task_s": by_task,
                         "equal": equal,
                         "load_average_before": load_before,
                         "load_average_between": load_between,
                         "load_average_after": load()})
            print(f"{name:9s} dask {wall:7.2f} s  one piece {one_wall:6.2f} s  "
                  f"x{wall / one_wall:.2f}  cpu {[round(c, 1) for c in worker_cpu]} / "
                  f"{one_cpu:.1f} s  worker peaks "
                  f"{[round(x / 2**30, 2) for x in peaks]} GiB  equal {equal}  "
                  f"load {load_before} -> {load()}", flush=True)
            print("    worker CPU s by task: " + ", ".join(
                f"{k} {v:.1f}" for k, v in by_task.items() if v >= 0.05), flush=True)
            del one
            shutil.rmtree(out, ignore_errors=True)
    devs = voxfield.devices()
    dev = next((d for d in devs if str(d["index"]) == device or d["type"] == device), devs[0])
    result = {"device": dev, "date": datetime.datetime.now(datetime.timezone.utc).isoformat(),
              "commit": git_commit(), "size": [n, n, n], "block": [b, b, b], "dtype": "uint8",
              "workers": args.workers, "threads_per_worker": 1,
              "worker_memory_limit": args.memory_limit, "cpus": os.cpu_count(),
              "nice": os.nice(0), "module": os.path.dirname(voxfield.__file__),
              "main_peak_rss_bytes": peak_rss_bytes(), "results": rows}
    if args.json:
        with open(args.json, "w") as f:
            json.dump(result, f, indent=1)
    shutil.rmtree(args.dir, ignore_errors=True)


if __name__ == "__main__":
    main()
