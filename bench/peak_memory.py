#!/usr/bin/env python3
"""Peak memory of `voxfield generate` and of the Python module over the PoCL baseline.

For each size N (floor-and-spheres world of bench/worlds.py) and each case, runs the command
under /usr/bin/time -v and records its peak resident set size; the baseline is the same command
on an 8^3 world (process, OpenCL platform, PoCL and the built kernels). Bytes per voxel =
(peak - baseline) / N^3. The module's figure is measured in a fresh Python process: its peak
after voxfield.distance_transform minus its peak after the same call on an 8^3 world, the
world array loaded before either.

  case           command
  l2-f32         generate W.npy -o F.npy --metric euclidean            (floor: 1 in + 4 out)
  l2-f32-indices ... --indices I.npy                                   (floor: 1 + 4 + 12;
                                                                        target <= 19, issue 29)
  l1-u16         generate W.npy -o F.npy                                (floor: 1 + 2)

Needs Debian's python3-numpy, /usr/bin/time and the built voxfield (and module for the module
rows). Run with /usr/bin/python3.
"""

import argparse
import datetime
import json
import os
import subprocess
import sys
import tempfile

import numpy as np

from worlds import make_world

from repo import REPO, git_commit  # noqa: E402
CASES = {
    "l2-f32": (["--metric", "euclidean"], False, 5),
    "l2-f32-indices": (["--metric", "euclidean"], True, 17),
    "l1-u16": ([], False, 3),
}
MODULE_CODE = r"""
import resource, sys
import numpy as np
sys.path.insert(0, sys.argv[1])
import voxfield
w = np.load(sys.argv[2])
voxfield.distance_transform(np.ascontiguousarray(w[:8, :8, :8]), metric='euclidean', device='cpu')
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
voxfield.distance_transform(w, metric='euclidean', device='cpu')
after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(before, after)
"""


def peak_kb(cmd):
    """Peak RSS (KB) of cmd under /usr/bin/time -v; exits 2 if the command fails."""
    with tempfile.NamedTemporaryFile(mode="r", suffix=".txt") as t:
        proc = subprocess.run(["/usr/bin/time", "-v", "-o", t.name] + cmd,
                              stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        if proc.returncode != 0:
            sys.stderr.write(proc.stderr)
            sys.exit(f"peak_memory: failed (exit {proc.returncode}): {' '.join(cmd)}")
        for line in t.read().splitlines():
            if "Maximum resident set size" in line:
                return int(line.split()[-1])
    sys.exit("peak_memory: /usr/bin/time printed no maximum resident set size")


def device_of(voxfield, world, tmp):
    """The device `generate --device cpu` runs on: name, platform, driver, compute units."""
    report = os.path.join(tmp, "device.json")
    subprocess.run([voxfield, "generate", world, "-o", os.path.join(tmp, "device.npy"),
                    "--device", "cpu", "--json", report], check=True, stdout=subprocess.DEVNULL)
    with open(report) as f:
        d = json.load(f)["device"]
    return {k: d[k] for k in ("name", "platform", "driver", "type", "compute_units")}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="256,512", help="world edges (default 256,512)")
    ap.add_argument("--seed", type=int, default=6683787)
    ap.add_argument("--voxfield", default=os.path.join(REPO, "build", "viewer", "voxfield"))
    ap.add_argument("--python-dir", default=os.path.join(REPO, "build", "python"))
    ap.add_argument("--no-module", action="store_true", help="skip the module rows")
    ap.add_argument("--json", help="write the rows to this JSON file")
    args = ap.parse_args()
    sizes = [int(s) for s in args.sizes.split(",") if s]
    rows = []
    with tempfile.TemporaryDirectory(prefix="voxfield_mem_") as tmp:
        tiny = os.path.join(tmp, "tiny.npy")
        np.save(tiny, make_world(8, args.seed))
        device = device_of(args.voxfield, tiny, tmp)
        field = os.path.join(tmp, "field.npy")
        idx = os.path.join(tmp, "indices.npy")

        def command(world, flags, indices):
            return ([args.voxfield, "generate", world, "-o", field, "--device", "cpu"] + flags +
                    (["--indices", idx] if indices else []))

        for n in sizes:
            world = os.path.join(tmp, f"world{n}.npy")
            np.save(world, make_world(n, args.seed))
            voxels = n ** 3
            for name, (flags, indices, floor) in CASES.items():
                base = peak_kb(command(tiny, flags, indices))
                peak = peak_kb(command(world, flags, indices))
                per = (peak - base) * 1024 / voxels
                rows.append({"case": name, "how": "voxfield generate", "size": n,
                             "baseline_kb": base, "peak_kb": peak,
                             "bytes_per_voxel_over_baseline": per, "floor_bytes_per_voxel": floor})
                print(f"{name:<15} {n:>4}^3 generate: peak {peak / 1024:8.1f} MiB, baseline "
                      f"{base / 1024:6.1f} MiB, {per:5.2f} B/voxel over it (floor {floor})",
                      flush=True)
            if not args.no_module:
                out = subprocess.run([sys.executable, "-c", MODULE_CODE, args.python_dir, world],
                                     check=True, capture_output=True, text=True).stdout.split()
                before, after = int(out[0]), int(out[1])
                per = (after - before) * 1024 / voxels
                rows.append({"case": "l2-f32", "how": "module distance_transform", "size": n,
                             "baseline_kb": before, "peak_kb": after,
                             "bytes_per_voxel_over_baseline": per, "floor_bytes_per_voxel": 4})
                print(f"{'l2-f32':<15} {n:>4}^3 module:   {per:5.2f} B/voxel over the process "
                      f"after an 8^3 call (floor 4: the output)", flush=True)
            os.remove(world)
    if args.json:
        record = {
            "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
            "commit": git_commit(),
            "device_arg": "cpu",
            "device": device,
            "world": f"floor+spheres seed={args.seed}",
            "loadavg": os.getloadavg(),
            "rows": rows,
        }
        with open(args.json, "w") as f:
            json.dump(record, f, indent=2)
            f.write("\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
