#!/usr/bin/env python3
"""Compare voxfield with SciPy's distance transforms: every metric, signed fields, sampling and indices.

On one world (a one-voxel floor plus random spheres, N^3, seeded; --input WORLD.npy; or with
--worlds, each named world of bench/worlds.py's benchmark set in turn) and in one run, each case
below is computed three ways and checked against SciPy:

  case                 voxfield                              SciPy (on mask = world == 0)
  manhattan            --metric manhattan                    distance_transform_cdt(mask, 'taxicab')
  manhattan-indices    ... --indices                         cdt(mask, 'taxicab', return_indices=True)
  chebyshev            --metric chebyshev                    cdt(mask, 'chessboard')
  euclidean            --metric euclidean (f32)              distance_transform_edt(mask)
  euclidean-sampling   ... --spacing X,Y,Z                   edt(mask, sampling=(z, y, x))
  euclidean-sampling-f64 ... --format f64                    edt(mask, sampling=(z, y, x))
  euclidean-indices    ... --indices                         edt(mask, return_indices=True)
  signed-manhattan     --signed (i16/i32)                    cdt(~solid) - cdt(solid), padded, cropped
  signed-euclidean     --signed --metric euclidean (f32)     edt(~solid) - edt(solid), padded, cropped

 1. `voxfield generate WORLD.npy -o FIELD.npy ... --json J --warmup W --repeat R`: the median of
    the R kernel times after W untimed runs (--warmup; OpenCL profiling events, the device-side
    figure);
 2. the plain command `voxfield generate WORLD.npy -o FIELD.npy ...`, R times: its median wall
    time (process start, device set-up, reading the world, the transform, writing the field);
 3. in process: `voxfield.distance_transform` of the Python module (imported from
    build/python, or --python-dir) on the same numpy array, after --warmup untimed calls;
    median and spread of R calls (time.perf_counter), its result checked against the CLI's;
and SciPy R times (median and spread, single-threaded host code) on the same array.

Checks: L1 and L-inf fields equal SciPy's voxel for voxel; L2 fields (float32) are within one
float32 ulp of SciPy's float64 rounded to float32 (DESIGN §3: correctly rounded), f64 fields
within two float64 ulp of SciPy's float64; indices
name a solid voxel at the field's distance (ties may pick another voxel than SciPy) and their
field matches SciPy's. cdt gives each non-zero element its distance to the nearest zero, so it
is fed the *empty* mask: solids are its zeros; elements outside the array are ignored, which is
DESIGN §3's "outside the world counts as empty". Signed fields pad the world with one empty voxel
on every side first (DESIGN §3). A world with no solid voxel has no zero in the mask (SciPy then
returns -1 or garbage) and the checks are skipped.

--voxfield-before BIN times a second binary (say, main's) on every case right after the first,
in the same run and against the same SciPy call; its kernel figures go under each case's
"before" key, its field is checked too, and --table prints its ratios in a row of their own.

Needs Debian's python3-numpy and python3-scipy (run with /usr/bin/python3) and the built
`voxfield` executable; the in-process figures need the built module (--no-module skips them).
Exit status: 0 if every check passed (or was skipped), 1 if one failed, 2 on bad usage or a
failed voxfield run.
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

from repo import REPO, git_commit  # noqa: E402
from worlds import WORLDS, make_named, make_world

CASES = ["manhattan", "manhattan-indices", "chebyshev", "euclidean", "euclidean-sampling",
         "euclidean-sampling-f64", "euclidean-indices", "signed-manhattan", "signed-euclidean"]


def spread(samples):
    """Median and spread of a list of milliseconds."""
    return {
        "median": statistics.median(samples),
        "min": min(samples),
        "max": max(samples),
        "std": statistics.stdev(samples) if len(samples) > 1 else 0.0,
        "samples": samples,
    }


def timed(fn, repeat, warmup=0):
    """(last result, [ms per call]) of `warmup` untimed and `repeat` timed calls of fn()."""
    result = None
    for _ in range(warmup):
        result = fn()
    ms = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        result = fn()
        ms.append((time.perf_counter() - t0) * 1e3)
    return result, ms


def ordered(a):
    """float32 values as integers in the same order, one apart per ulp (for ulp distances)."""
    i = np.ascontiguousarray(a, dtype=np.float32).view(np.int32).astype(np.int64)
    return np.where(i < 0, -(i & 0x7FFFFFFF), i)


def ordered64(a):
    """float64 values as integers in the same order, one apart per ulp."""
    i = np.ascontiguousarray(a, dtype=np.float64).view(np.int64)
    return np.where(i < 0, -(i & 0x7FFFFFFFFFFFFFFF), i)


def compare(ours, theirs, exact):
    """(ok, detail): equal voxel for voxel (exact), within two float64 ulp (f64 fields) or
    within one float32 ulp."""
    if ours.shape != theirs.shape:
        return False, f"shape {ours.shape}, expected {theirs.shape}"
    if exact:
        bad = ours.astype(np.float64) != theirs.astype(np.float64)
        worst = None
    elif ours.dtype == np.float64:
        ulps = np.abs(ordered64(ours) - ordered64(theirs))
        bad = ulps > 2
        worst = int(ulps.max())
    else:
        ulps = np.abs(ordered(ours) - ordered(theirs.astype(np.float32)))
        bad = ulps > 1
        worst = int(ulps.max())
    if not bad.any():
        return True, "equal" if exact else f"max {worst} ulp"
    idx = tuple(int(i) for i in np.argwhere(bad)[0])
    return False, (f"{int(bad.sum())} voxels differ{'' if exact else f' (max {worst} ulp)'}; "
                   f"first (z,y,x)={idx}: ours {ours[idx]}, scipy {theirs[idx]}")


def check_indices(world, field, idx, metric, sampling):
    """(ok, detail): every index names a solid voxel at the field's distance."""
    if idx.shape != (3,) + world.shape or idx.dtype != np.int32:
        return False, f"indices have shape {idx.shape} dtype {idx.dtype}"
    if not (world[idx[0], idx[1], idx[2]] != 0).all():
        return False, "an index names an empty voxel"
    grid = np.ogrid[tuple(slice(0, n) for n in world.shape)]
    parts = [np.abs(idx[a] - grid[a]).astype(np.float64) * sampling[a] for a in range(3)]
    if metric == "manhattan":
        d = parts[0] + parts[1] + parts[2]
        return compare(field, d, exact=True)
    d = np.sqrt(parts[0] ** 2 + parts[1] ** 2 + parts[2] ** 2)
    return compare(field, d, exact=False)


def padded_signed(world, transform):
    solid = np.pad(world != 0, 1, constant_values=False)
    return (transform(~solid) - transform(solid))[1:-1, 1:-1, 1:-1]


def make_case(name, world, sampling_zyx):
    """The CLI flags, module keywords, SciPy call and check of one case."""
    shape = world.shape
    mask = world == 0
    l1_fmt = "u16" if sum(shape) - 3 <= 0xFFFF else "u32"
    linf_fmt = "u16" if max(shape) - 1 <= 0xFFFF else "u32"
    signed_fmt = "i16" if sum(shape) - 3 <= 0x7FFF else "i32"
    unit = (1.0, 1.0, 1.0)
    if name == "manhattan":
        return dict(flags=["--metric", "manhattan", "--format", l1_fmt],
                    kwargs=dict(metric="manhattan", format=l1_fmt), exact=True,
                    scipy_call="distance_transform_cdt(mask, metric='taxicab')",
                    scipy=lambda: ndimage.distance_transform_cdt(mask, metric="taxicab"))
    if name == "manhattan-indices":
        return dict(flags=["--metric", "manhattan", "--format", l1_fmt], indices=True,
                    kwargs=dict(metric="manhattan", format=l1_fmt, return_indices=True),
                    exact=True, metric="manhattan", sampling=unit,
                    scipy_call="distance_transform_cdt(mask, metric='taxicab', return_indices=True)",
                    scipy=lambda: ndimage.distance_transform_cdt(mask, metric="taxicab",
                                                                 return_indices=True))
    if name == "chebyshev":
        return dict(flags=["--metric", "chebyshev", "--format", linf_fmt],
                    kwargs=dict(metric="chebyshev", format=linf_fmt), exact=True,
                    scipy_call="distance_transform_cdt(mask, metric='chessboard')",
                    scipy=lambda: ndimage.distance_transform_cdt(mask, metric="chessboard"))
    if name == "euclidean":
        return dict(flags=["--metric", "euclidean"], kwargs=dict(metric="euclidean"), exact=False,
                    scipy_call="distance_transform_edt(mask)",
                    scipy=lambda: ndimage.distance_transform_edt(mask))
    if name == "euclidean-sampling":
        z, y, x = sampling_zyx
        return dict(flags=["--metric", "euclidean", "--spacing", f"{x!r},{y!r},{z!r}"],
                    kwargs=dict(metric="euclidean", sampling=sampling_zyx), exact=False,
                    scipy_call=f"distance_transform_edt(mask, sampling={sampling_zyx})",
                    scipy=lambda: ndimage.distance_transform_edt(mask, sampling=sampling_zyx))
    if name == "euclidean-sampling-f64":
        z, y, x = sampling_zyx
        return dict(flags=["--metric", "euclidean", "--format", "f64",
                           "--spacing", f"{x!r},{y!r},{z!r}"],
                    kwargs=dict(metric="euclidean", sampling=sampling_zyx, format="f64"),
                    exact=False,
                    scipy_call=f"distance_transform_edt(mask, sampling={sampling_zyx})",
                    scipy=lambda: ndimage.distance_transform_edt(mask, sampling=sampling_zyx))
    if name == "euclidean-indices":
        return dict(flags=["--metric", "euclidean"], indices=True,
                    kwargs=dict(metric="euclidean", return_indices=True), exact=False,
                    metric="euclidean", sampling=unit,
                    scipy_call="distance_transform_edt(mask, return_indices=True)",
                    scipy=lambda: ndimage.distance_transform_edt(mask, return_indices=True))
    if name == "signed-manhattan":
        def cdt(m):
            return ndimage.distance_transform_cdt(m, metric="taxicab")
        return dict(flags=["--signed", "--metric", "manhattan", "--format", signed_fmt],
                    kwargs=dict(metric="manhattan", signed=True, format=signed_fmt), exact=True,
                    scipy_call="cdt(~solid, 'taxicab') - cdt(solid, 'taxicab'), padded by 1, cropped",
                    scipy=lambda: padded_signed(world, cdt))
    if name == "signed-euclidean":
        return dict(flags=["--signed", "--metric", "euclidean"],
                    kwargs=dict(metric="euclidean", signed=True), exact=False,
                    scipy_call="edt(~solid) - edt(solid), padded by 1, cropped",
                    scipy=lambda: padded_signed(world, ndimage.distance_transform_edt))
    raise ValueError(name)


def run_cli(cmd):
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    ms = (time.perf_counter() - t0) * 1e3
    if proc.returncode != 0:
        sys.stderr.write(proc.stderr)
        sys.stderr.write(f"compare_scipy: voxfield failed (exit {proc.returncode}): {' '.join(cmd)}\n")
        sys.exit(2)
    return ms


def import_module(python_dir):
    sys.path.insert(0, python_dir)
    try:
        import voxfield
    except ImportError as e:
        sys.stderr.write(f"compare_scipy: cannot import the voxfield module from {python_dir} ({e}); "
                         f"build it (target voxfield_python), pass --python-dir, or --no-module\n")
        sys.exit(2)
    return voxfield


def run_world(world, args, module, cases, sampling):
    """(rows, device info) of every case on one world, as the table and JSON report them."""
    voxels = int(world.size)
    solid = int(np.count_nonzero(world))
    rows = []
    device_info = None
    with tempfile.TemporaryDirectory(prefix="voxfield_scipy_") as tmp:
        world_path = os.path.join(tmp, "world.npy")
        np.save(world_path, world)
        for name in cases:
            case = make_case(name, world, sampling)
            field_path = os.path.join(tmp, "field.npy")
            json_path = os.path.join(tmp, "run.json")
            idx_path = os.path.join(tmp, "indices.npy")
            base = [args.voxfield, "generate", world_path, "-o", field_path, "--device",
                    args.device] + case["flags"] + (["--indices", idx_path] if case.get("indices")
                                                   else [])
            load_before = os.getloadavg()
            print(f"{name}: voxfield (kernels, then {args.command_repeat} plain commands) ...",
                  file=sys.stderr)
            run_cli(base + ["--json", json_path, "--warmup", str(args.warmup), "--repeat",
                             str(args.repeat)])
            with open(json_path) as f:
                j = json.load(f)
            device_info = j["device"]
            command_ms = [run_cli(base) for _ in range(args.command_repeat)]
            ours = np.load(field_path)
            ours_idx = np.load(idx_path) if case.get("indices") else None
            before = None
            if args.voxfield_before:
                # The same case by the other binary, right after (its field checked too).
                print(f"{name}: voxfield before ({args.voxfield_before}) ...", file=sys.stderr)
                run_cli([args.voxfield_before] + base[1:] +
                        ["--json", json_path, "--warmup", str(args.warmup), "--repeat",
                         str(args.repeat)])
                with open(json_path) as f:
                    jb = json.load(f)
                before = {"binary": args.voxfield_before, "label": args.before_label,
                          "kernel_ms": spread([float(v) for v in jb["kernel_ms_samples"]]),
                          "stages_ms": jb.get("stages"), "field": np.load(field_path)}

            print(f"{name}: SciPy {case['scipy_call']} ...", file=sys.stderr)
            theirs, scipy_ms = timed(case["scipy"], args.scipy_repeat)
            theirs_field = theirs[0] if case.get("indices") else theirs

            module_ms = None
            module_same = None
            if module is not None:
                out, module_ms = timed(
                    lambda: module.distance_transform(world, device=args.device, **case["kwargs"]),
                    args.repeat, args.warmup)
                if case.get("indices"):
                    module_same = bool(np.array_equal(out[0], ours) and
                                       np.array_equal(out[1], ours_idx))
                else:
                    module_same = bool(out.dtype == ours.dtype and np.array_equal(out, ours))

            if solid == 0:
                ok, detail = None, "no solid voxel"
            else:
                ok, detail = compare(ours, theirs_field, case["exact"])
                if ok and case.get("indices"):
                    ok, d2 = check_indices(world, ours, ours_idx, case["metric"], case["sampling"])
                    detail += "; indices " + ("name a solid voxel at the field's distance"
                                              if ok else d2)
                if module_same is False:
                    ok, detail = False, detail + "; the module's result differs from the CLI's"

            if before is not None:
                field_before = before.pop("field")
                if solid == 0:
                    before["check_ok"], before["check"] = None, "no solid voxel"
                else:
                    before["check_ok"], before["check"] = compare(field_before, theirs_field,
                                                                  case["exact"])
                    ok = ok if before["check_ok"] else False
                    if not before["check_ok"]:
                        detail += "; before: " + before["check"]

            kernel = spread([float(v) for v in j["kernel_ms_samples"]])
            command = spread(command_ms) if command_ms else None
            scipy_t = spread(scipy_ms)
            module_t = spread(module_ms) if module_ms else None
            rows.append({
                "case": name,
                "scipy_call": case["scipy_call"],
                "voxfield_flags": case["flags"] + (["--indices"] if case.get("indices") else []),
                "format": j["format"],
                "check_ok": ok,
                "check": detail,
                "module_equals_cli": module_same,
                "kernel_ms": kernel,
                "stages_ms": j.get("stages"),
                "end_to_end_ms": float(j["end_to_end_ms"]),
                "command_wall_ms": command,
                "module_ms": module_t,
                "scipy_ms": scipy_t,
                "ratio_scipy_over_kernel": scipy_t["median"] / kernel["median"],
                "ratio_scipy_over_command": scipy_t["median"] / command["median"]
                if command else None,
                "ratio_scipy_over_module": scipy_t["median"] / module_t["median"]
                if module_t else None,
                "loadavg_1min_before_after": [load_before[0], os.getloadavg()[0]],
            })
            if before is not None:
                before["ratio_scipy_over_kernel"] = (scipy_t["median"] /
                                                     before["kernel_ms"]["median"])
                rows[-1]["before"] = before
    return rows, device_info


def print_rows(rows, device_name, args):
    print(f"device: {device_name} (--device {args.device}); medians of {args.repeat} kernel runs,"
          f" {args.scipy_repeat} SciPy calls"
          f" (module after {args.warmup} warm-up calls)")
    print(f"{'case':<22} {'format':>6} {'kernel ms':>10} {'command ms':>11} {'module ms':>10}"
          f" {'scipy ms':>10} {'scipy/kernel':>12} {'scipy/cmd':>9} {'scipy/module':>12}  check")
    nan = float("nan")
    for r in rows:
        mod = r["module_ms"]["median"] if r["module_ms"] else nan
        cmd = r["command_wall_ms"]["median"] if r["command_wall_ms"] else nan
        print(f"{r['case']:<22} {r['format']:>6} {r['kernel_ms']['median']:>10.3f}"
              f" {cmd:>11.1f} {mod:>10.3f}"
              f" {r['scipy_ms']['median']:>10.1f} {r['ratio_scipy_over_kernel']:>12.1f}"
              f" {r['ratio_scipy_over_command'] or nan:>9.2f}"
              f" {r['ratio_scipy_over_module'] or nan:>12.1f}"
              f"  {'ok' if r['check_ok'] else ('skipped' if r['check_ok'] is None else 'FAILED')}:"
              f" {r['check']}")


def print_table(paths):
    """A markdown table, case x world, of SciPy / kernel medians from --worlds JSON files."""
    worlds = []
    for path in paths:
        with open(path) as f:
            record = json.load(f)
        for w in record.get("worlds", []):
            worlds.append((w, record))
    if not worlds:
        sys.exit("compare_scipy: --table: no --worlds results in " + ", ".join(paths))
    cases = []
    for w, _ in worlds:
        for r in w["comparisons"]:
            if r["case"] not in cases:
                cases.append(r["case"])
    print("| case | " + " | ".join(w["name"] for w, _ in worlds) + " |")
    print("| --- |" + " ---: |" * len(worlds))
    for c in cases:
        cells = []
        for w, _ in worlds:
            r = next((x for x in w["comparisons"] if x["case"] == c), None)
            if r is None:
                cells.append("-")
                continue
            k = r["kernel_ms"]
            cells.append(f"{r['ratio_scipy_over_kernel']:.1f}x ({k['median']:.0f} ms, "
                         f"{k['min']:.0f}-{k['max']:.0f}; SciPy {r['scipy_ms']['median']:.0f})"
                         + ("" if r["check_ok"] is not False else " FAILED"))
        print(f"| {c} | " + " | ".join(cells) + " |")
        if any("before" in x for w, _ in worlds for x in w["comparisons"] if x["case"] == c):
            cells = []
            for w, _ in worlds:
                r = next((x for x in w["comparisons"] if x["case"] == c), None)
                b = r.get("before") if r else None
                if b is None:
                    cells.append("-")
                    continue
                k = b["kernel_ms"]
                cells.append(f"{b['ratio_scipy_over_kernel']:.1f}x ({k['median']:.0f} ms, "
                             f"{k['min']:.0f}-{k['max']:.0f})"
                             + ("" if b["check_ok"] is not False else " FAILED"))
            label = next(x["before"]["label"] for w, _ in worlds for x in w["comparisons"]
                         if x["case"] == c and "before" in x)
            print(f"| {c} ({label}) | " + " | ".join(cells) + " |")
    loads = [v for w, _ in worlds for r in w["comparisons"]
             for v in r.get("loadavg_1min_before_after", [])]
    records = {id(rec): rec for _, rec in worlds}.values()
    print(f"\nDevice {worlds[0][1]['device']}; commits "
          f"{', '.join(sorted({rec['commit'][:8] for rec in records}))}; dates "
          f"{min(rec['date'] for rec in records)} to {max(rec['date'] for rec in records)}; "
          f"1-minute load average {min(loads):.1f} to {max(loads):.1f} during the runs.")


def main():
    if len(sys.argv) > 1 and sys.argv[1] == "--table":
        print_table(sys.argv[2:])
        return 0
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 epilog="compare_scipy.py --table FILE.json ... prints the "
                                        "case x world markdown table of --worlds results.")
    ap.add_argument("--size", type=int, default=256, help="world edge N (N^3 voxels; default 256)")
    ap.add_argument("--seed", type=int, default=6683787, help="world seed")
    ap.add_argument("--input", help="use this (Z,Y,X) uint8/16/32 .npy world instead")
    ap.add_argument("--worlds",
                    help=f"comma-separated worlds of bench/worlds.py ({','.join(WORLDS).replace('%', '%%')}) or "
                         f"'all': run every case on each (instead of the one world)")
    ap.add_argument("--voxfield", default=os.path.join(REPO, "build", "viewer", "voxfield"),
                    help="voxfield binary (default: build/viewer/voxfield)")
    ap.add_argument("--voxfield-before",
                    help="a second voxfield binary (say, main's) timed on every case right after "
                         "the first, in the same run, its field checked against SciPy's too")
    ap.add_argument("--before-label", default="before",
                    help="the name of --voxfield-before in the table (default: before)")
    ap.add_argument("--python-dir", default=os.path.join(REPO, "build", "python"),
                    help="folder holding the built voxfield module (default: build/python)")
    ap.add_argument("--no-module", action="store_true", help="skip the in-process comparison")
    ap.add_argument("--device", default="cpu", help="voxfield --device / device= (default: cpu)")
    ap.add_argument("--repeat", type=int, default=5, help="timed runs of each (default 5)")
    ap.add_argument("--command-repeat", type=int,
                    help="timed plain `voxfield generate` commands per case (default: --repeat; "
                         "0 skips them)")
    ap.add_argument("--scipy-repeat", type=int,
                    help="timed SciPy calls per case (default: --repeat)")
    ap.add_argument("--warmup", type=int, default=1,
                    help="untimed runs before the timed ones: the CLI's --warmup and in-process "
                         "calls (default 1)")
    ap.add_argument("--cases", default=",".join(CASES),
                    help=f"comma-separated subset of {','.join(CASES)} (default: all)")
    ap.add_argument("--sampling", default="2,1,0.5",
                    help="sampling (z,y,x) of euclidean-sampling, SciPy's order (default 2,1,0.5)")
    ap.add_argument("--json", help="write the comparison to this JSON file")
    args = ap.parse_args()

    if args.command_repeat is None:
        args.command_repeat = args.repeat
    if args.scipy_repeat is None:
        args.scipy_repeat = args.repeat
    if args.repeat < 1 or args.scipy_repeat < 1 or args.warmup < 0 or args.command_repeat < 0:
        ap.error("--repeat and --scipy-repeat must be at least 1, --warmup and --command-repeat "
                 "at least 0")
    cases = [c for c in args.cases.split(",") if c]
    unknown = [c for c in cases if c not in CASES]
    if unknown or not cases:
        ap.error(f"--cases: unknown {','.join(unknown) or '(none given)'}; expected {','.join(CASES)}")
    try:
        sampling = tuple(float(v) for v in args.sampling.split(","))
    except ValueError:
        sampling = ()
    if len(sampling) != 3 or not all(v > 0 and np.isfinite(v) for v in sampling):
        ap.error(f"--sampling '{args.sampling}': expected three positive numbers z,y,x")
    for binary in [args.voxfield] + ([args.voxfield_before] if args.voxfield_before else []):
        if not (os.path.isfile(binary) and os.access(binary, os.X_OK)):
            ap.error(f"voxfield binary not found: {binary} (build it first, or pass --voxfield)")
    if args.size < 1:
        ap.error("--size must be at least 1")
    names = []
    if args.worlds:
        names = WORLDS if args.worlds == "all" else [w for w in args.worlds.split(",") if w]
        bad = [w for w in names if w not in WORLDS]
        if bad or not names:
            ap.error(f"--worlds: unknown {','.join(bad) or '(none given)'}; expected "
                     f"{','.join(WORLDS)} or all")
        if args.input:
            ap.error("--worlds and --input exclude each other")
    module = None if args.no_module else import_module(args.python_dir)

    if names:
        worlds = [(name, lambda name=name: make_named(name, args.size, args.seed)) for name in names]
    elif args.input:
        loaded = np.load(args.input)
        if loaded.ndim != 3:
            ap.error(f"{args.input}: expected a 3-D (Z,Y,X) array, got shape {loaded.shape}")
        worlds = [(args.input, lambda: loaded)]
    else:
        worlds = [(f"floor+spheres N={args.size} seed={args.seed}",
                   lambda: make_world(args.size, args.seed))]

    results = []
    device_name = None
    device_info = None
    failed = False
    for source, make in worlds:
        world = make()
        voxels = int(world.size)
        solid = int(np.count_nonzero(world))
        print(f"world: {source}, shape (Z,Y,X) {world.shape}, {voxels} voxels, {solid} solid")
        rows, device_info = run_world(world, args, module, cases, sampling)
        device_name = device_info["name"]
        print_rows(rows, device_name, args)
        failed = failed or any(r["check_ok"] is False for r in rows)
        results.append({"world": source, "size": [int(world.shape[2]), int(world.shape[1]),
                                                  int(world.shape[0])],
                        "voxels": voxels, "solid": solid, "rows": rows})
    print("kernel = OpenCL profiling of the kernels (median after 1 warm-up run); command = wall "
          "time of a whole `voxfield generate` (start-up, read, transform, write); module = "
          "voxfield.distance_transform in this process (array in, array out); scipy = the "
          "SciPy call's wall time on the host.")
    if len(results) > 1:
        print("\nSciPy / kernel (medians), case x world:")
        print(f"{'case':<22} " + " ".join(f"{r['world']:>13}" for r in results))
        for c in cases:
            cells = []
            for r in results:
                row = next(x for x in r["rows"] if x["case"] == c)
                mark = "" if row["check_ok"] is not False else "!"
                cells.append(f"{row['ratio_scipy_over_kernel']:>12.1f}{mark or ' '}")
            print(f"{c:<22} " + " ".join(cells))

    if args.json:
        common = {
            "device": device_name,
            "device_info": device_info,
            "device_arg": args.device,
            "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
            "commit": git_commit(),
            "repeat": args.repeat,
            "command_repeat": args.command_repeat,
            "scipy_repeat": args.scipy_repeat,
            "warmup": args.warmup,
            "cpu_count": os.cpu_count(),
            "numpy": np.__version__,
            "scipy": __import__("scipy").__version__,
            "voxfield": args.voxfield,
            "voxfield_before": args.voxfield_before,
            "before_label": args.before_label if args.voxfield_before else None,
        }
        if names:
            record = dict(common, size_arg=args.size, seed=args.seed,
                          all_checks_pass=not failed,
                          worlds=[{"name": r["world"], "size": r["size"], "voxels": r["voxels"],
                                   "solid": r["solid"], "comparisons": r["rows"]}
                                  for r in results])
        else:
            r = results[0]
            rows = r["rows"]
            record = dict(common, world=r["world"], size=r["size"], voxels=r["voxels"],
                          solid=r["solid"],
                          all_checks_pass=None if r["solid"] == 0 else not failed,
                          comparisons=rows)
            by_case = {x["case"]: x for x in rows}
            taxicab = by_case.get("manhattan")
            edt = by_case.get("euclidean")
            if taxicab:  # the summary fields bench/summarize.py tabulates (the taxicab comparison)
                record.update({
                    "ours_kernel_ms_median": taxicab["kernel_ms"]["median"],
                    "ours_end_to_end_ms_median": taxicab["end_to_end_ms"],
                    "scipy_ms_median": taxicab["scipy_ms"]["median"],
                    "ratio_scipy_over_ours_kernel": taxicab["ratio_scipy_over_kernel"],
                    "equal": taxicab["check_ok"],
                    "scipy_edt_ms_median": edt["scipy_ms"]["median"] if edt else None,
                })
        with open(args.json, "w") as f:
            json.dump(record, f, indent=2)
            f.write("\n")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
