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
The world's pages are warmed by an untimed run. Each run also reports its set-up and upload
phases (generate --json phases_ms setup + upload: device, kernel build and upload, where the
cache acts), less noisy than the whole process on a shared machine. Prints medians and writes
them, every sample, the device, date, commit and load average to --json.
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

from repo import REPO, git_commit  # noqa: E402
JOBS = {"l1-u16": [], "l2-f32": ["--metric", "euclidean"]}


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

        def run(flags, xdg, pocl, off=False):
            env = dict(os.environ, XDG_CACHE_HOME=xdg, POCL_CACHE_DIR=pocl)
            env.pop("VOXFIELD_NO_PROGRAM_CACHE", None)
            if off:
                env["VOXFIELD_NO_PROGRAM_CACHE"] = "1"
            report = os.path.join(tmp, "report.json")
            cmd = [args.voxfield, "generate", world, "-o", field, "--device", args.device,
                   "--json", report] + flags
            t0 = time.perf_counter()
            proc = subprocess.run(cmd, env=env, stdout=subprocess.DEVNULL,
                                  stderr=subprocess.PIPE, text=True)
            wall = (time.perf_counter() - t0) * 1e3
            if proc.returncode != 0:
                sys.stderr.write(proc.stderr)
                sys.exit(f"program_cache: failed (exit {proc.returncode}): {' '.join(cmd)}")
            with open(report) as f:
                r = json.load(f)
            return wall, r["phases_ms"]["setup"] + r["phases_ms"]["upload"], r["device"]

        def fresh(name):
            path = os.path.join(tmp, name)
            shutil.rmtree(path, ignore_errors=True)
            os.makedirs(path)
            return path

        results = {}
        device = None
        for job, flags in JOBS.items():
            # Cold: both caches empty. Then PoCL's kernels stay compiled in pocl_warm.
            cold, cold_setup, _ = run(flags, fresh("xdg-cold"), fresh("pocl-cold"))
            _, _, d = run(flags, fresh("xdg-warmup"), pocl_warm)
            device = {k: d[k] for k in ("name", "platform", "driver", "type", "compute_units")}
            walls = {"first": [], "cached": [], "off": []}
            setups = {"first": [], "cached": [], "off": []}
            for _ in range(args.repeat):
                xdg = fresh("xdg-round")
                for name, off in (("first", False), ("cached", False), ("off", True)):
                    wall, setup, _ = run(flags, xdg, pocl_warm, off=off)
                    walls[name].append(wall)
                    setups[name].append(setup)
            wall_med = {k: statistics.median(v) for k, v in walls.items()}
            setup_med = {k: statistics.median(v) for k, v in setups.items()}
            results[job] = {"flags": flags, "cold_ms": cold, "cold_setup_upload_ms": cold_setup,
                            "median_ms": wall_med, "median_setup_upload_ms": setup_med,
                            "samples_ms": walls, "samples_setup_upload_ms": setups}
            print(f"{job}: {args.size}^3 generate, whole process (median of {args.repeat}): "
                  f"cold {cold:.0f} ms, first {wall_med['first']:.0f}, cached "
                  f"{wall_med['cached']:.0f}, off {wall_med['off']:.0f}; setup+upload: cold "
                  f"{cold_setup:.0f} ms, first {setup_med['first']:.1f}, cached "
                  f"{setup_med['cached']:.1f}, off {setup_med['off']:.1f}", flush=True)

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
