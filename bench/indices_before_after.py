#!/usr/bin/env python3
"""`voxfield generate --indices` of two or more binaries on the benchmark worlds, interleaved.

Usage (on the machine that times them, e.g. the H200):
    python3 bench/indices_before_after.py --size 512 --device gpu --repeat 10 \\
        --bin before=/tmp/vf/bin/voxfield-before --bin after=/tmp/vf/bin/voxfield \\
        --json bench/results/h200-indices-ties-COMMIT.json

For each world of bench/worlds.py (--worlds; N^3 voxels, seeded) and each metric of --metrics,
the binaries run one after the other, --rounds times (so drift falls on all alike): each
`voxfield generate WORLD.npy -o F.npy --metric M --indices I.npy --device D --warmup W
--repeat R --json J`, of which the median kernel time (OpenCL profiling events) and each
stage's median are kept. The index planes of the binaries are compared (the share of voxels
naming the same solid), and each binary's are checked to name a solid at the field's
distance. With SciPy importable and --scipy-size (default 128; 0: none) the euclidean indices
on that world are also compared with SciPy's distance_transform_edt(world == 0,
return_indices=True). Writes every sample, the binaries' versions and the load to --json
(after each world).
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from worlds import WORLDS, make_named  # noqa: E402


def run(exe, world, metric, device, warmup, repeat, tmp, label):
    field = os.path.join(tmp, f"field-{label}.npy")
    idx = os.path.join(tmp, f"idx-{label}.npy")
    js = os.path.join(tmp, f"run-{label}.json")
    cmd = [exe, "generate", world, "-o", field, "--metric", metric, "--indices", idx,
           "--device", device, "--warmup", str(warmup), "--repeat", str(repeat), "--json", js]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        sys.stderr.write(proc.stdout + proc.stderr)
        sys.exit(f"indices_before_after: {' '.join(cmd)} failed ({proc.returncode})")
    with open(js) as f:
        doc = json.load(f)
    return doc, field, idx


def check(world, field, idx, metric):
    """Every index names a solid at the field's distance (float32 field: 1 ulp)."""
    w = np.load(world, mmap_mode="r")
    d = np.load(field, mmap_mode="r")
    ix = np.load(idx, mmap_mode="r")
    ok = True
    for z0 in range(0, w.shape[0], 32):
        sl = slice(z0, min(z0 + 32, w.shape[0]))
        planes = np.asarray(ix[:, sl])
        if not np.all(w[tuple(planes)] != 0):
            return False
        grid = np.indices(planes.shape[1:])
        grid[0] += z0
        off = np.abs(planes - grid).astype(np.float64)
        if metric == "euclidean":
            want = np.sqrt((off * off).sum(axis=0))
        elif metric == "manhattan":
            want = off.sum(axis=0)
        else:
            want = off.max(axis=0)
        got = np.asarray(d[sl], dtype=np.float64)
        ok = ok and bool(np.all(np.abs(got - want) <= 2.0 ** -23 * want))
    return ok


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--bin", action="append", required=True, help="LABEL=PATH (repeatable)")
    p.add_argument("--size", type=int, default=256)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--worlds", default="random-50%,random-1%,clustered,terrain,floor-spheres")
    p.add_argument("--metrics", default="euclidean,manhattan")
    p.add_argument("--device", default="gpu")
    p.add_argument("--warmup", type=int, default=2)
    p.add_argument("--repeat", type=int, default=10)
    p.add_argument("--rounds", type=int, default=2)
    p.add_argument("--scipy-size", type=int, default=128)
    p.add_argument("--json", default="")
    args = p.parse_args()
    bins = [tuple(b.split("=", 1)) for b in args.bin]
    names = WORLDS if args.worlds == "all" else args.worlds.split(",")
    report = {"size": args.size, "device": args.device, "seed": args.seed, "worlds": {},
              "binaries": {}}
    for label, exe in bins:
        out = subprocess.run([exe, "--version"], capture_output=True, text=True).stdout.strip()
        report["binaries"][label] = {"path": exe, "version": out}
    with tempfile.TemporaryDirectory(prefix="vf_ties_") as tmp:
        for name in names:
            world = os.path.join(tmp, "world.npy")
            np.save(world, make_named(name, args.size, args.seed))
            entry = report["worlds"].setdefault(name, {"load": os.getloadavg()[0]})
            for metric in args.metrics.split(","):
                rows = {label: {"kernel_ms": [], "stages": []} for label, _ in bins}
                files = {}
                for _ in range(args.rounds):
                    for label, exe in bins:
                        doc, field, idx = run(exe, world, metric, args.device, args.warmup,
                                              args.repeat, tmp, label)
                        rows[label]["kernel_ms"] += doc["kernel_ms_samples"]
                        rows[label]["stages"].append(doc.get("stages"))
                        files[label] = (field, idx)
                first = np.load(files[bins[0][0]][1], mmap_mode="r")
                for label, _ in bins:
                    r = rows[label]
                    r["median_ms"] = statistics.median(r["kernel_ms"])
                    r["check"] = check(world, *files[label], metric)
                    same = np.all(np.load(files[label][1], mmap_mode="r") == first, axis=0)
                    r[f"same_as_{bins[0][0]}"] = float(np.mean(same))
                entry[metric] = rows
                print(f"{name:14s} {metric:10s} " + "  ".join(
                    f"{label} {rows[label]['median_ms']:.3f} ms"
                    f"{'' if rows[label]['check'] else ' CHECK FAILED'}"
                    f" (same as {bins[0][0]}: {100 * rows[label][f'same_as_{bins[0][0]}']:.1f}%)"
                    for label, _ in bins) + f"  load {entry['load']:.2f}", flush=True)
            save(report, args.json)
        if args.scipy_size:
            try:
                from scipy import ndimage
            except ImportError:
                report["scipy"] = "not importable"
            else:
                report["scipy"] = {}
                for name in names:
                    w = make_named(name, args.scipy_size, args.seed)
                    world = os.path.join(tmp, "small.npy")
                    np.save(world, w)
                    _, want = ndimage.distance_transform_edt(w == 0, return_indices=True)
                    for label, exe in bins:
                        _, _, idx = run(exe, world, "euclidean", args.device, 0, 1, tmp, label)
                        share = float(np.mean(np.all(np.load(idx) == want, axis=0)))
                        report["scipy"].setdefault(name, {})[label] = share
                        print(f"{name:14s} {args.scipy_size}^3 euclidean indices as SciPy's: "
                              f"{label} {100 * share:.2f}%", flush=True)
    save(report, args.json)


def save(report, path):
    if path:
        with open(path, "w") as f:
            json.dump(report, f, indent=1)


if __name__ == "__main__":
    main()
