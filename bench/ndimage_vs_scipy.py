#!/usr/bin/env python3
"""voxfield.ndimage against scipy.ndimage, in one process, on the same numpy array.

Usage (module built into build/python, or installed by pip):
    PYTHONPATH=build/python VOXFIELD_DEVICE=cpu python3 bench/ndimage_vs_scipy.py --size 256 \
        --repeat 5 --json bench/results/pocl-ndimage-vs-scipy-256.json

On the floor + spheres world of compare_scipy.py (bench/worlds.py; N^3, seeded), the input
is `world == 0` (nonzero where empty, so both measure from the empty voxels to the nearest
solid). After one untimed call each, the median of --repeat wall-time calls of
distance_transform_edt (float64) and distance_transform_cdt (taxicab, chessboard; int32),
SciPy's and voxfield's, the edt with return_indices too, and the edt into a caller's
distances= array (voxfield writes a C-contiguous one in place). Checks: edt equal bit for bit, cdt
equal, indices naming a nearest zero; records the share of indices that break ties as SciPy's.
Writes device, date, commit, the module's path, the load averages before and after, and every
sample to --json. To compare two builds, run the script once with each on PYTHONPATH.
"""

import argparse
import datetime
import json
import os
import statistics
import subprocess
import sys
import time

import numpy as np
from scipy import ndimage as sp

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from worlds import make_world  # noqa: E402

import voxfield  # noqa: E402
from voxfield import ndimage as vf  # noqa: E402

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def timed(call, repeat):
    call()
    samples = []
    for _ in range(repeat):
        t = time.perf_counter()
        out = call()
        samples.append((time.perf_counter() - t) * 1e3)
    return out, {"median_ms": statistics.median(samples), "min_ms": min(samples),
                 "max_ms": max(samples), "samples_ms": samples}


def commit():
    if os.environ.get("VOXFIELD_COMMIT"):
        return os.environ["VOXFIELD_COMMIT"]
    try:
        return subprocess.run(["git", "-C", REPO, "rev-parse", "HEAD"], capture_output=True,
                              text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--size", type=int, default=256)
    p.add_argument("--repeat", type=int, default=5)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--json", default="")
    args = p.parse_args()
    n = args.size
    a = make_world(n, args.seed) == 0
    device = next((d for d in voxfield.devices()
                   if d["index"] == int(os.environ["VOXFIELD_DEVICE"])), None) \
        if os.environ.get("VOXFIELD_DEVICE", "").isdigit() else None
    if device is None:
        kind = os.environ.get("VOXFIELD_DEVICE", "gpu")
        devs = voxfield.devices()
        device = next((d for d in devs if d["type"] == kind), devs[0])
    rows = []
    load_before = [round(x, 2) for x in os.getloadavg()]

    want, t_sp = timed(lambda: sp.distance_transform_edt(a), args.repeat)
    got, t_vf = timed(lambda: vf.distance_transform_edt(a), args.repeat)
    assert np.array_equal(got, want), "edt differs from SciPy"
    rows.append({"function": "distance_transform_edt", "scipy": t_sp, "voxfield": t_vf,
                 "speedup": t_sp["median_ms"] / t_vf["median_ms"], "bit_for_bit": True})

    out_sp, out_vf = np.empty(a.shape), np.empty(a.shape)
    _, t_sp = timed(lambda: sp.distance_transform_edt(a, distances=out_sp), args.repeat)
    _, t_vf = timed(lambda: vf.distance_transform_edt(a, distances=out_vf), args.repeat)
    assert np.array_equal(out_vf, out_sp), "edt into distances= differs from SciPy"
    rows.append({"function": "distance_transform_edt(distances=out)", "scipy": t_sp,
                 "voxfield": t_vf, "speedup": t_sp["median_ms"] / t_vf["median_ms"],
                 "bit_for_bit": True})
    del out_sp, out_vf

    (wd, wi), t_sp = timed(lambda: sp.distance_transform_edt(a, return_indices=True),
                           args.repeat)
    (gd, gi), t_vf = timed(lambda: vf.distance_transform_edt(a, return_indices=True),
                           args.repeat)
    assert np.array_equal(gd, wd)
    assert np.all(a[tuple(gi)] == 0)
    off = (gi - np.indices(a.shape)).astype(np.float64)
    assert np.array_equal(np.sqrt((off * off).sum(axis=0)), wd), "indices not nearest"
    same = float(np.mean(np.all(gi == wi, axis=0)))
    nonzero = a != 0
    same_nonzero = float(np.mean(np.all(gi == wi, axis=0)[nonzero]))
    rows.append({"function": "distance_transform_edt(return_indices=True)", "scipy": t_sp,
                 "voxfield": t_vf, "speedup": t_sp["median_ms"] / t_vf["median_ms"],
                 "indices_as_scipy": same, "indices_as_scipy_on_nonzero": same_nonzero})

    for metric in ("taxicab", "chessboard"):
        want, t_sp = timed(lambda: sp.distance_transform_cdt(a, metric=metric), args.repeat)
        got, t_vf = timed(lambda: vf.distance_transform_cdt(a, metric=metric), args.repeat)
        assert np.array_equal(got, want), f"cdt {metric} differs from SciPy"
        rows.append({"function": f"distance_transform_cdt(metric='{metric}')", "scipy": t_sp,
                     "voxfield": t_vf, "speedup": t_sp["median_ms"] / t_vf["median_ms"],
                     "equal": True})

    for r in rows:
        print(f"{r['function']:48s} scipy {r['scipy']['median_ms']:9.1f} ms  voxfield "
              f"{r['voxfield']['median_ms']:8.1f} ms  x{r['speedup']:.1f}")
    out = {"device": device, "date": datetime.datetime.now(datetime.timezone.utc).isoformat(),
           "commit": commit(), "size": [n, n, n], "repeat": args.repeat,
           "cpus": os.cpu_count(), "module": os.path.dirname(voxfield.__file__),
           "load_average_before": load_before,
           "load_average_after": [round(x, 2) for x in os.getloadavg()], "results": rows}
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
