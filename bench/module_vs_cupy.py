#!/usr/bin/env python3
"""The Python module on a GPU against CuPy, in one process, on the same numpy array.

Usage (on the NVIDIA machine, with the module built for its Python, e.g. `PYTHONPATH=DIR`):
    python3 bench/module_vs_cupy.py --size 512 --repeat 10 --json bench/results/h200-module-vs-cupy-512.json

On the floor + spheres world of compare_scipy.py (bench/worlds.py; N^3, seeded), for euclidean
(float32) and manhattan (uint16; CuPy has only the Euclidean transform, so its EDT is the
timing peer there), after --warmup untimed calls, the median and spread of --repeat calls of:
  - voxfield.distance_transform(world, metric=M, device="gpu"): numpy in, numpy out (upload,
    kernels, download: transfers included), wall time (time.perf_counter);
  - CuPy, transfers included: cp.asarray(world == 0), distance_transform_edt(...,
    float64_distances=False), .get(), wall time;
  - CuPy, transfers excluded: distance_transform_edt on the mask already on the GPU, CUDA
    events around the call.
voxfield's transfers-excluded figure is its kernel time, which `voxfield generate --json`
reports (compare_cupy.py). Checks: euclidean within one float32 ulp of CuPy's float64 EDT.
Writes device, date, commit ($VOXFIELD_COMMIT, else git's) and every sample to --json. Needs numpy, CuPy and the module.
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

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from worlds import make_world  # noqa: E402

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def spread(samples):
    return {"median": statistics.median(samples), "min": min(samples), "max": max(samples),
            "std": statistics.pstdev(samples), "samples": samples}


def wall(fn, warmup, repeat):
    for _ in range(warmup):
        fn()
    out = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        out.append((time.perf_counter() - t) * 1000.0)
    return spread(out)


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--size", type=int, default=512)
    p.add_argument("--seed", type=int, default=6683787)
    p.add_argument("--repeat", type=int, default=10)
    p.add_argument("--warmup", type=int, default=2)
    p.add_argument("--json")
    a = p.parse_args()
    try:
        import cupy as cp
        from cupyx.scipy import ndimage as cnd
        import voxfield
    except ImportError as e:
        sys.exit(f"module_vs_cupy: {e} (needs CuPy and the voxfield module on PYTHONPATH)")
    world = make_world(a.size, a.seed)
    mask_gpu = cp.asarray(world == 0)
    results = []
    for metric, dtype in (("euclidean", np.float32), ("manhattan", np.uint16)):
        ours = voxfield.distance_transform(world, metric=metric, device="gpu")
        assert ours.dtype == dtype, ours.dtype
        t_ours = wall(lambda: voxfield.distance_transform(world, metric=metric, device="gpu"),
                      a.warmup, a.repeat)

        def cupy_with_transfers():
            m = cp.asarray(world == 0)
            d = cnd.distance_transform_edt(m, float64_distances=False)
            return d.get()

        t_cupy = wall(cupy_with_transfers, a.warmup, a.repeat)
        events = []
        for i in range(a.warmup + a.repeat):
            start, stop = cp.cuda.Event(), cp.cuda.Event()
            start.record()
            cnd.distance_transform_edt(mask_gpu, float64_distances=False)
            stop.record()
            stop.synchronize()
            if i >= a.warmup:
                events.append(cp.cuda.get_elapsed_time(start, stop))
        t_cupy_device = spread(events)
        check = "timing peer only (CuPy's EDT is L2)"
        if metric == "euclidean":
            ref = cnd.distance_transform_edt(mask_gpu).get()
            rel = np.abs(ours.astype(np.float64) - ref) / np.maximum(ref, 1e-30)
            worst = float(rel[ref > 0].max()) if (ref > 0).any() else 0.0
            check = f"max relative difference {worst:.3g} (one float32 ulp: {2**-23:.3g})"
            if worst > 2**-23:
                check = "DIFFERENT: " + check
        row = {"metric": metric, "dtype": str(ours.dtype),
               "voxfield_module_ms": t_ours, "cupy_with_transfers_ms": t_cupy,
               "cupy_device_ms": t_cupy_device,
               "cupy_with_transfers_over_module": t_cupy["median"] / t_ours["median"],
               "check": check}
        results.append(row)
        print(f"{metric:10s} module {t_ours['median']:8.2f} ms   CuPy with transfers "
              f"{t_cupy['median']:8.2f} ms   CuPy on the device {t_cupy_device['median']:8.2f} ms"
              f"   CuPy/module {row['cupy_with_transfers_over_module']:.2f}   {check}")
    doc = {"date": datetime.datetime.now(datetime.timezone.utc).isoformat(),
           "commit": os.environ.get("VOXFIELD_COMMIT") or subprocess.run(
               ["git", "-C", REPO, "rev-parse", "HEAD"], capture_output=True,
               text=True).stdout.strip() or None,
           "devices": voxfield.devices(), "cupy": cp.__version__, "numpy": np.__version__,
           "size": [a.size] * 3, "seed": a.seed, "repeat": a.repeat, "warmup": a.warmup,
           "results": results}
    if a.json:
        with open(a.json, "w") as f:
            json.dump(doc, f, indent=1)
    return 1 if any(r["check"].startswith("DIFFERENT") for r in results) else 0


if __name__ == "__main__":
    sys.exit(main())
