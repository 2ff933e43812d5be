#!/usr/bin/env python3
"""Compare `voxfield generate` (exact Manhattan field) with SciPy's chamfer distance transform.

Builds a world (a one-voxel floor plus random spheres, N^3, seeded; or --input WORLD.npy),
runs `voxfield generate WORLD.npy -o FIELD.npy --format F --device D --json J --warmup 1
--repeat R` and takes the median of the R kernel times (OpenCL profiling of the kernels only:
the fair device-side figure; the untimed first run pays page faults and kernel set-up), and
reports end_to_end_ms (upload + first run + download in that process, kernel build
included) beside it. F is u16 when every possible distance (X+Y+Z-3) fits in it, else u32:
the narrowest format that holds the exact field, as a user would pick. It times
scipy.ndimage.distance_transform_cdt(world == 0, metric='taxicab') as often (median of
time.perf_counter wall time, single-threaded host code) and checks that both fields are
identical. It also times scipy.ndimage.distance_transform_edt(world == 0) (Euclidean
distance: a DIFFERENT metric from ours, so it is reported as a separate figure for scale and
never compared for equality; --no-edt skips it).

cdt gives each non-zero element its distance to the nearest zero element, so it is fed the
*empty* mask: solids are its zeros. Elements outside the array are ignored by cdt, which is
DESIGN §3's "outside the world counts as empty". A world with no solid voxel has no zero in
the mask (cdt then returns -1 everywhere) and the equality check is skipped.

Needs Debian's python3-numpy and python3-scipy (run with /usr/bin/python3). Exit status: 0 if
the fields are equal (or the check was skipped), 1 if they differ, 2 on bad usage or a failed
voxfield run.
"""

import argparse
import datetime
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np
from scipy import ndimage

from worlds import make_world

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def git_commit():
    try:
        out = subprocess.run(
            ["git", "-C", REPO, "rev-parse", "HEAD"],
            check=True,
            capture_output=True,
            text=True,
        )
        return out.stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def run_voxfield(exe, world_path, field_path, json_path, device, repeat, fmt):
    cmd = [exe, "generate", world_path, "-o", field_path, "--format", fmt, "--json", json_path,
           "--warmup", "1", "--repeat", str(repeat)]
    if device:
        cmd += ["--device", device]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        sys.stderr.write(proc.stderr)
        sys.stderr.write(f"compare_scipy: voxfield failed (exit {proc.returncode}): {' '.join(cmd)}\n")
        sys.exit(2)
    with open(json_path) as f:
        return json.load(f)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", type=int, default=256, help="world edge N (N^3 voxels; default 256)")
    ap.add_argument("--seed", type=int, default=6683787, help="world seed")
    ap.add_argument("--input", help="use this (Z,Y,X) uint8/16/32 .npy world instead")
    ap.add_argument(
        "--voxfield",
        default=os.path.join(REPO, "build", "viewer", "voxfield"),
        help="voxfield binary (default: build/viewer/voxfield)",
    )
    ap.add_argument("--device", default="cpu", help="voxfield --device (default: cpu)")
    ap.add_argument("--repeat", type=int, default=5, help="runs of each (default 5)")
    ap.add_argument("--json", help="write the comparison to this JSON file")
    ap.add_argument("--no-edt", action="store_true",
                    help="do not time distance_transform_edt (Euclidean, a different metric)")
    args = ap.parse_args()

    if args.repeat < 1:
        ap.error("--repeat must be at least 1")
    if not (os.path.isfile(args.voxfield) and os.access(args.voxfield, os.X_OK)):
        ap.error(f"voxfield binary not found: {args.voxfield} (build it first, or pass --voxfield)")

    with tempfile.TemporaryDirectory(prefix="voxfield_scipy_") as tmp:
        if args.input:
            world = np.load(args.input)
            if world.ndim != 3:
                ap.error(f"{args.input}: expected a 3-D (Z,Y,X) array, got shape {world.shape}")
            world_path = os.path.abspath(args.input)
            source = args.input
        else:
            if args.size < 1:
                ap.error("--size must be at least 1")
            world = make_world(args.size, args.seed)
            world_path = os.path.join(tmp, "world.npy")
            np.save(world_path, world)
            source = f"floor+spheres N={args.size} seed={args.seed}"
        field_path = os.path.join(tmp, "field.npy")
        json_path = os.path.join(tmp, "run.json")
        voxels = int(world.size)
        solid = int(np.count_nonzero(world))
        print(f"world: {source}, shape (Z,Y,X) {world.shape}, {voxels} voxels, {solid} solid")

        fmt = "u16" if sum(world.shape) - 3 <= 0xFFFF else "u32"
        j = run_voxfield(args.voxfield, world_path, field_path, json_path, args.device,
                         args.repeat, fmt)
        kernel_ms = [float(v) for v in j["kernel_ms_samples"]]
        e2e_ms = [float(j["end_to_end_ms"])]
        device_name = j["device"]["name"]
        ours = np.load(field_path)

        mask = world == 0
        scipy_ms = []
        theirs = None
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            theirs = ndimage.distance_transform_cdt(mask, metric="taxicab")
            scipy_ms.append((time.perf_counter() - t0) * 1e3)
        # Euclidean EDT: another metric, timed for scale only (float64 output).
        edt_ms = []
        if not args.no_edt:
            for _ in range(args.repeat):
                t0 = time.perf_counter()
                ndimage.distance_transform_edt(mask)
                edt_ms.append((time.perf_counter() - t0) * 1e3)

    want_dtype = np.uint16 if fmt == "u16" else np.uint32
    if ours.shape != world.shape or ours.dtype != want_dtype:
        print(f"our field has shape {ours.shape} dtype {ours.dtype}, expected {world.shape} "
              f"{np.dtype(want_dtype).name}")
        equal = False
        checked = True
    elif solid == 0:
        equal = None  # cdt has no zero to measure to; DESIGN says ours is all the format's max
        checked = False
    else:
        diff = ours.astype(np.int64) != theirs.astype(np.int64)
        equal = not bool(diff.any())
        checked = True
        if not equal:
            idx = tuple(int(i) for i in np.argwhere(diff)[0])
            print(
                f"fields differ at {int(diff.sum())} voxels; first (z,y,x)={idx}: "
                f"ours {int(ours[idx])}, scipy {int(theirs[idx])}"
            )

    ours_med = statistics.median(kernel_ms)
    e2e_med = statistics.median(e2e_ms)
    scipy_med = statistics.median(scipy_ms)
    ratio = scipy_med / ours_med if ours_med > 0 else float("inf")
    equal_text = "skipped (no solid voxel)" if not checked else ("yes" if equal else "NO")

    print(f"device: {device_name} (--device {args.device}); {args.repeat} runs each, medians")
    print(f"{'voxels':>12} {'ours ms':>10} {'scipy ms':>10} {'scipy/ours':>10}  equal")
    print(f"{voxels:>12} {ours_med:>10.3f} {scipy_med:>10.3f} {ratio:>10.1f}  {equal_text}")
    if edt_ms:
        edt_med = statistics.median(edt_ms)
        print(f"scipy distance_transform_edt (EUCLIDEAN, a different metric; not compared): "
              f"{edt_med:.3f} ms median, edt/ours = {edt_med / ours_med:.1f}")
    print(
        f"ours = OpenCL kernel time (profiling events; the fair device-side figure). "
        f"ours end to end (process-internal: upload + kernels + download + kernel build): "
        f"{e2e_med:.3f} ms, scipy/end-to-end = "
        f"{(scipy_med / e2e_med if e2e_med > 0 else float('inf')):.2f}. "
        f"scipy = distance_transform_cdt wall time on the host."
    )

    if args.json:
        record = {
            "device": device_name,
            "device_arg": args.device,
            "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
            "commit": git_commit(),
            "world": source,
            "size": [int(world.shape[2]), int(world.shape[1]), int(world.shape[0])],
            "voxels": voxels,
            "solid": solid,
            "repeat": args.repeat,
            "ours_kernel_ms_median": ours_med,
            "ours_end_to_end_ms_median": e2e_med,
            "scipy_ms_median": scipy_med,
            "ratio_scipy_over_ours_kernel": ratio,
            "ours_kernel_ms": kernel_ms,
            "ours_end_to_end_ms": e2e_ms,
            "scipy_ms": scipy_ms,
            "equal": equal,
            "scipy_edt_ms_median": statistics.median(edt_ms) if edt_ms else None,
            "scipy_edt_ms": edt_ms,
            "scipy_edt_metric": "euclidean (different from ours: timed for scale, not compared)",
            "numpy": np.__version__,
            "scipy": __import__("scipy").__version__,
        }
        with open(args.json, "w") as f:
            json.dump(record, f, indent=2)
            f.write("\n")

    return 1 if checked and not equal else 0


if __name__ == "__main__":
    sys.exit(main())
