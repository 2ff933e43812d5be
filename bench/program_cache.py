#!/usr/bin/env python3
"""`voxfield generate` as a whole process with and without the disk cache of built programs.

Usage: /usr/bin/python3 bench/program_cache.py [--voxfield build/viewer/voxfield] [--size 256]
           [--repeat 5] [--device cpu] [--json OUT.json]

Writes the N^3 floor-and-spheres world (bench/worlds.py make_world) and, for two jobs (the
default u16 Manhattan field and an f32 Euclidean one, which build different programs), times
the whole process (start to exit, the output written) in R rounds of three conditions:
  first    an empty voxfield program cache ($XDG_CACHE_HOME a fresh folder): the run builds its
           programs from source and writes the cache entries;
  cached   the cache those first runs filled: the programs load from their entries;
  off      $VOXFIELD_NO_PROGRAM_CACHE=1: built from source every run (the behaviour before the
           cache).
PoCL keeps its own cache of compiled kernels ($POCL_CACHE_DIR, pointed at one folder warmed
before the rounds), so every condition finds PoCL's kernels compiled, as a user's second run of
anything would; "cold" adds one run with both caches empty (a first run on a fresh machine).
The world's pages are warmed by an untimed run. Prints medians and writes them, every sample,
the device, date, commit and load average to --json.
"""

import argparse
import datetime
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

from worlds import make_world

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
JOBS = {"l1-u16": [], "l2-f32": ["--metric", "euclidean"]}


def git_commit():
    try:
        out = subprocess.run(["git", "-C", REPO, "rev-parse", "HEAD"], check=True,
                             capture_output=True, text=True)
        return out.stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--voxfield", default=os.path.join(REPO, "build", "viewer", "voxfield"))
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--seed", type=int, default=6683787)
    ap.add_argument("--json", help="write the results to this JSON file")
    args = ap.parse_args()
    if args.repeat < 1 or args.size < 8:
        sys.exit("program_cache: --repeat must be >= 1 and --size >= 8")

    with tempfile.TemporaryDirectory(prefix="voxfield_pcache_") as tmp:
        world = os.path.join(tmp, "world.npy")
        field = os.path.join(tmp, "field.npy")
        np.save(world, make_world(args.size, args.seed))
        pocl_warm = os.path.join(tmp, "pocl-warm")
        os.makedirs(pocl_warm)

        def run(flags, xdg, pocl, off=False, report=None):
            env = dict(os.environ, XDG_CACHE_HOME=xdg, POCL_CACHE_DIR=pocl)
            env.pop("VOXFIELD_NO_PROGRAM_CACHE", None)
            if off:
                env["VOXFIELD_NO_PROGRAM_CACHE"] = "1"
            cmd = [args.voxfield, "generate", world, "-o", field, "--device", args.device] + flags
            if report:
                cmd += ["--json", report]
            t0 = time.perf_counter()
            proc = subprocess.run(cmd, env=env, stdout=subprocess.DEVNULL,
                                  stderr=subprocess.PIPE, text=True)
            wall = (time.perf_counter() - t0) * 1e3
            if proc.returncode != 0:
                sys.stderr.write(proc.stderr)
                sys.exit(f"program_cache: failed (exit {proc.returncode}): {' '.join(cmd)}")
            return wall

        def fresh(name):
            path = os.path.join(tmp, name)
            shutil.rmtree(path, ignore_errors=True)
            os.makedirs(path)
            return path

        results = {}
        device = None
        for job, flags in JOBS.items():
            # Cold: both caches empty. Then PoCL's kernels stay compiled in pocl_warm.
            cold = run(flags, fresh("xdg-cold"), fresh("pocl-cold"))
            report = os.path.join(tmp, "report.json")
            run(flags, fresh("xdg-warmup"), pocl_warm, report=report)
            with open(report) as f:
                d = json.load(f)["device"]
            device = {k: d[k] for k in ("name", "platform", "driver", "type", "compute_units")}
            samples = {"first": [], "cached": [], "off": []}
            for _ in range(args.repeat):
                xdg = fresh("xdg-round")
                samples["first"].append(run(flags, xdg, pocl_warm))
                samples["cached"].append(run(flags, xdg, pocl_warm))
                samples["off"].append(run(flags, xdg, pocl_warm, off=True))
            medians = {k: statistics.median(v) for k, v in samples.items()}
            results[job] = {"flags": flags, "cold_ms": cold, "median_ms": medians,
                            "samples_ms": samples}
            print(f"{job}: {args.size}^3 generate, whole process: cold {cold:7.1f} ms, first "
                  f"{medians['first']:6.1f} ms, cached {medians['cached']:6.1f} ms, off "
                  f"{medians['off']:6.1f} ms (median of {args.repeat}); cached saves "
                  f"{medians['first'] - medians['cached']:5.1f} ms", flush=True)

    if args.json:
        record = {
            "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
            "commit": git_commit(),
            "device_arg": args.device,
            "device": device,
            "world": f"floor+spheres {args.size}^3 seed={args.seed}",
            "repeat": args.repeat,
            "loadavg": os.getloadavg(),
            "jobs": results,
        }
        with open(args.json, "w") as f:
            json.dump(record, f, indent=2)
            f.write("\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
