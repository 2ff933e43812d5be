#!/usr/bin/env python3
"""Compare voxfield's exact field on an NVIDIA GPU with CuPy's distance_transform_edt (PBA+).

Usage (on the NVIDIA machine, after building voxfield):
    python3 bench/compare_cupy.py --size 256 --voxfield build/viewer/voxfield --repeat 20 \
        --json bench/results/h100-vs-cupy-256.json

In one run, on one machine:
  1. builds the floor + spheres world of compare_scipy.py (bench/worlds.py; N^3, seeded);
  2. runs `voxfield generate WORLD.npy --format u16 --device gpu --warmup W --repeat R --json`
     and takes the median of the R kernel times (OpenCL profiling events);
  3. times cupyx.scipy.ndimage.distance_transform_edt(world == 0) on the GPU with CUDA events
     around each call, after W untimed warm-up calls, and takes the median of R calls (the
     array is on the GPU before timing; float64 output as SciPy's; also float32 where CuPy
     supports float64_distances=False);
  4. prints the ratios CuPy / ours.

What is checked, where the metric allows it:
  - ours is Manhattan (L1), CuPy's EDT Euclidean: the fields are NOT comparable for equality.
    Instead every voxel must satisfy EDT <= ours <= sqrt(3) * EDT (the Euclidean and the
    Manhattan distance to the nearest solid bound each other this way), a consistency check.
  - CuPy's EDT is compared with SciPy's distance_transform_edt on a small grid (--check-size,
    default 64) of the same kind: they must agree to 1e-6 (needs SciPy; skipped, and said so,
    without it).

Needs numpy and CuPy (e.g. `pip install cupy-cuda12x`) with an NVIDIA GPU; fails with exit 2
and a message naming what is missing otherwise. Exit status: 0 if the checks pass, 1 if one
fails, 2 on bad usage, missing CuPy or a failed voxfield run.
"""

import argparse
import datetime
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def fail(message):
    sys.stderr.write(f"compare_cupy: {message}\n")
    sys.exit(2)


try:
    import numpy as np
except ImportError:
    fail("numpy is missing (Debian: apt-get install python3-numpy)")

from worlds import make_world  # noqa: E402  (needs numpy)


def import_cupy():
    try:
        import cupy as cp
        from cupyx.scipy import ndimage as cnd
    except ImportError as e:
        fail(f"CuPy is not installed ({e}); this comparison needs an NVIDIA GPU with CuPy, "
             "e.g. `pip install cupy-cuda12x` (it cannot run on the PoCL/CPU machine)")
    try:
        count = cp.cuda.runtime.getDeviceCount()
    except Exception as e:  # cupy raises CUDARuntimeError without a driver
        fail(f"CuPy finds no usable CUDA device ({e})")
    if count < 1:
        fail("CuPy finds no CUDA device")
    return cp, cnd


def git_commit():
    try:
        out = subprocess.run(["git", "-C", REPO, "rev-parse", "HEAD"], check=True,
                             capture_output=True, text=True)
        return out.stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def run_voxfield(exe, world_path, field_path, json_path, device, warmup, repeat):
    cmd = [exe, "generate", world_path, "-o", field_path, "--format", "u16", "--json", json_path,
           "--warmup", str(warmup), "--repeat", str(repeat)]
    if device:
        cmd += ["--device", device]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        sys.stderr.write(proc.stderr)
        fail(f"voxfield failed (exit {proc.returncode}): {' '.join(cmd)}")
    with open(json_path) as f:
        return json.load(f)


def time_cupy(cp, fn, warmup, repeat):
    """Median of `repeat` CUDA-event timings of fn() after `warmup` untimed calls (ms)."""
    for _ in range(warmup):
        fn()
    cp.cuda.Device().synchronize()
    samples = []
    for _ in range(repeat):
        start, end = cp.cuda.Event(), cp.cuda.Event()
        start.record()
        fn()
        end.record()
        end.synchronize()
        samples.append(float(cp.cuda.get_elapsed_time(start, end)))
    return samples


def check_against_scipy(cp, cnd, n, seed):
    """CuPy EDT vs SciPy EDT on a small world: (status text, max abs difference or None)."""
    try:
        from scipy import ndimage
    except ImportError:
        return "skipped: SciPy is not installed (apt-get install python3-scipy)", None
    mask = make_world(n, seed) == 0
    ref = ndimage.distance_transform_edt(mask)
    got = cp.asnumpy(cnd.distance_transform_edt(cp.asarray(mask)))
    diff = float(np.max(np.abs(got.astype(np.float64) - ref))) if ref.size else 0.0
    return ("equal" if diff <= 1e-6 else "DIFFERENT"), diff


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", type=int, default=256, help="world edge N (N^3; default 256)")
    ap.add_argument("--seed", type=int, default=6683787, help="world seed")
    ap.add_argument("--voxfield", default=os.path.join(REPO, "build", "viewer", "voxfield"),
                    help="voxfield binary (default: build/viewer/voxfield)")
    ap.add_argument("--device", default="gpu", help="voxfield --device (default: gpu)")
    ap.add_argument("--repeat", type=int, default=20, help="timed runs of each (default 20)")
    ap.add_argument("--warmup", type=int, default=3, help="untimed runs first (default 3)")
    ap.add_argument("--check-size", type=int, default=64,
                    help="edge of the small world on which CuPy is checked against SciPy")
    ap.add_argument("--json", help="write the comparison to this JSON file")
    args = ap.parse_args()
    if args.repeat < 1 or args.size < 1 or args.check_size < 1 or args.warmup < 0:
        ap.error("--size, --repeat and --check-size must be at least 1, --warmup at least 0")
    if not (os.path.isfile(args.voxfield) and os.access(args.voxfield, os.X_OK)):
        ap.error(f"voxfield binary not found: {args.voxfield} (build it first, or pass --voxfield)")
    if args.json and os.path.dirname(args.json) and not os.path.isdir(os.path.dirname(args.json)):
        ap.error(f"--json {args.json}: folder does not exist")
    cp, cnd = import_cupy()

    world = make_world(args.size, args.seed)
    source = f"floor+spheres N={args.size} seed={args.seed}"
    with tempfile.TemporaryDirectory(prefix="voxfield_cupy_") as tmp:
        world_path = os.path.join(tmp, "world.npy")
        field_path = os.path.join(tmp, "field.npy")
        json_path = os.path.join(tmp, "run.json")
        np.save(world_path, world)
        ours_doc = run_voxfield(args.voxfield, world_path, field_path, json_path, args.device,
                                args.warmup, args.repeat)
        ours = np.load(field_path)
    ours_ms = [float(v) for v in ours_doc["kernel_ms_samples"]]
    ours_med = statistics.median(ours_ms)

    mask_gpu = cp.asarray(world == 0)
    edt64_ms = time_cupy(cp, lambda: cnd.distance_transform_edt(mask_gpu), args.warmup,
                         args.repeat)
    edt32_ms = None
    try:
        cnd.distance_transform_edt(mask_gpu, float64_distances=False)
        edt32_ms = time_cupy(
            cp, lambda: cnd.distance_transform_edt(mask_gpu, float64_distances=False),
            args.warmup, args.repeat)
    except TypeError:
        pass  # older CuPy: float64 only
    edt = cp.asnumpy(cnd.distance_transform_edt(mask_gpu))

    # Bounds between the metrics (ours is L1): EDT <= L1 <= sqrt(3) EDT, voxel by voxel.
    solid = int(np.count_nonzero(world))
    if solid == 0:
        bounds_ok, bounds_text = None, "skipped (no solid voxel)"
    else:
        l1 = ours.astype(np.float64)
        bad = (l1 < edt - 1e-9) | (l1 > math.sqrt(3) * edt + 1e-9)
        bounds_ok = not bool(bad.any())
        bounds_text = "hold" if bounds_ok else f"VIOLATED at {int(bad.sum())} voxels"
    scipy_status, scipy_diff = check_against_scipy(cp, cnd, args.check_size, args.seed)

    edt64_med = statistics.median(edt64_ms)
    props = cp.cuda.runtime.getDeviceProperties(cp.cuda.Device().id)
    gpu_name = props["name"].decode() if isinstance(props["name"], bytes) else str(props["name"])
    print(f"world: {source}, {world.size} voxels, {solid} solid")
    print(f"ours:  {ours_doc['device']['name']} (--device {args.device}), exact L1, u16: "
          f"{ours_med:.3f} ms median kernel time of {args.repeat}")
    print(f"cupy:  {gpu_name}, distance_transform_edt (EUCLIDEAN, PBA+), float64: "
          f"{edt64_med:.3f} ms median of {args.repeat} (CUDA events, after {args.warmup} warm-up)")
    if edt32_ms:
        print(f"cupy:  float64_distances=False: {statistics.median(edt32_ms):.3f} ms median")
    print(f"ratio: cupy float64 / ours = {edt64_med / ours_med:.2f}" +
          (f", cupy float32 / ours = {statistics.median(edt32_ms) / ours_med:.2f}"
           if edt32_ms else ""))
    print("check: ours (L1) vs CuPy (Euclidean): different metrics, not compared for equality; "
          f"EDT <= L1 <= sqrt(3) EDT {bounds_text}")
    print(f"check: CuPy EDT vs SciPy EDT on {args.check_size}^3: {scipy_status}"
          + (f" (max |diff| {scipy_diff:.2e})" if scipy_diff is not None else ""))

    if args.json:
        record = {
            "device": ours_doc["device"]["name"],
            "device_arg": args.device,
            "cupy_device": gpu_name,
            "driver": ours_doc["device"].get("driver"),
            "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
            # The voxfield binary's own commit (the checkout on the GPU machine may differ).
            "commit": ours_doc.get("commit") or git_commit(),
            "world": source,
            "size": [int(world.shape[2]), int(world.shape[1]), int(world.shape[0])],
            "repeat": args.repeat,
            "warmup": args.warmup,
            "ours_metric": "manhattan",
            "ours_kernel_ms_median": ours_med,
            "ours_kernel_ms": ours_ms,
            "cupy_metric": "euclidean (different from ours: not compared for equality)",
            "cupy_edt_ms_median": edt64_med,
            "cupy_edt_ms": edt64_ms,
            "cupy_edt_f32_ms_median": statistics.median(edt32_ms) if edt32_ms else None,
            "cupy_edt_f32_ms": edt32_ms,
            "ratio_cupy_over_ours_kernel": edt64_med / ours_med if ours_med > 0 else None,
            "bounds_l1_vs_edt_hold": bounds_ok,
            "cupy_vs_scipy_edt": scipy_status,
            "cupy_vs_scipy_edt_max_abs_diff": scipy_diff,
            "cupy_vs_scipy_check_size": args.check_size,
            "cupy": cp.__version__,
            "cuda_driver": cp.cuda.runtime.driverGetVersion(),
            "numpy": np.__version__,
        }
        with open(args.json, "w") as f:
            json.dump(record, f, indent=2)
            f.write("\n")

    failed = bounds_ok is False or scipy_status == "DIFFERENT"
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
