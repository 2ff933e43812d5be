#!/usr/bin/env python3
"""voxfield.ndimage against scipy.ndimage on the benchmark worlds, one or more builds, same run.

Usage (module built into build/python, or installed by pip):
    VOXFIELD_DEVICE=cpu python3 bench/ndimage_vs_scipy.py --size 256 --repeat 5 \\
        --build after=build/python --build before=/tmp/before/python@356a7d3 \\
        --json bench/results/pocl-ndimage-vs-scipy-worlds-256.json

For each world of bench/worlds.py (--worlds, default all; N^3 voxels, seeded) the input is
`world == 0` (nonzero where empty, so both measure from the empty voxels to the nearest
solid). SciPy runs in this process: the median of --scipy-repeat calls of
distance_transform_edt (float64) and of distance_transform_edt(return_indices=True); its
results go to a temporary folder. Then each --build (LABEL=PYTHONPATH; default: the module
this process imports, labelled "voxfield") runs in a child process on the same world, one
after the other per world so that the machine's load falls on them alike: after one untimed
call each, the median of --repeat wall-time calls of its distance_transform_edt, of the edt
into a caller's distances= array, and of the edt with return_indices (and with --cdt the
taxicab and chessboard distance_transform_cdt against SciPy's), each with its median CPU
time (user + system of the process, PoCL's threads included: the machine's other load moves
it far less than the wall time; SciPy's CPU time is its one thread's). Checks, in the child: edt
equal to SciPy's bit for bit, indices naming a zero element at exactly SciPy's distance; it
records the share of indices equal to SciPy's (ties may break otherwise). Writes device,
date, commit, each build's module path and commit, the load averages beside every world,
and every sample to --json.
"""

import argparse
import datetime
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
sys.path.insert(0, HERE)
from worlds import WORLDS, make_named  # noqa: E402


def cpu_seconds():
    """This process's CPU time (user + system, all its threads: PoCL's workers included)."""
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def timed(call, repeat, warmup=1):
    """Median wall time of `repeat` calls after `warmup`, and their median CPU time (which the
    machine's other load moves far less than the wall time)."""
    for _ in range(warmup):
        call()
    samples = []
    cpu = []
    out = None
    for _ in range(repeat):
        c = cpu_seconds()
        t = time.perf_counter()
        out = call()
        samples.append((time.perf_counter() - t) * 1e3)
        cpu.append((cpu_seconds() - c) * 1e3)
    return out, {"median_ms": statistics.median(samples), "min_ms": min(samples),
                 "max_ms": max(samples), "samples_ms": samples,
                 "cpu_median_ms": statistics.median(cpu), "cpu_samples_ms": cpu}


def git_commit(path):
    try:
        return subprocess.run(["git", "-C", path, "rev-parse", "HEAD"], capture_output=True,
                              text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def load():
    return [round(x, 2) for x in os.getloadavg()]


def child(args):
    """One build on one world: times and checks voxfield against SciPy's saved results."""
    import voxfield
    from scipy import ndimage as sp
    from voxfield import ndimage as vf

    a = make_named(args.world, args.size, args.seed) == 0
    want = np.load(os.path.join(args.scipy_dir, "edt.npy"))
    rows = {"module": os.path.dirname(voxfield.__file__),
            "commit": os.environ.get("VOXFIELD_COMMIT") or
            git_commit(os.path.dirname(voxfield.__file__)),
            "load_before": load()}
    got, rows["edt"] = timed(lambda: vf.distance_transform_edt(a), args.repeat)
    assert np.array_equal(got, want), "edt differs from SciPy"
    del got
    out = np.empty(a.shape)
    _, rows["edt_out"] = timed(lambda: vf.distance_transform_edt(a, distances=out), args.repeat)
    assert np.array_equal(out, want), "edt into distances= differs from SciPy"
    del out
    (gd, gi), rows["indices"] = timed(
        lambda: vf.distance_transform_edt(a, return_indices=True), args.index_repeat)
    assert np.array_equal(gd, want), "edt with indices differs from SciPy"
    del gd
    assert np.all(a[tuple(gi)] == 0), "an index names a nonzero element"
    off = gi - np.indices(a.shape, dtype=np.int32)
    sq = np.zeros(a.shape, np.int64)
    for axis in range(a.ndim):
        sq += off[axis].astype(np.int64) ** 2
    del off
    assert np.array_equal(np.sqrt(sq.astype(np.float64)), want), "indices not nearest"
    del sq
    wi = np.load(os.path.join(args.scipy_dir, "ft.npy"), mmap_mode="r")
    same = np.all(gi == wi, axis=0)
    rows["indices_as_scipy"] = float(np.mean(same))
    rows["indices_as_scipy_on_nonzero"] = float(np.mean(same[a != 0]))
    del gi, wi, same
    if args.cdt:
        for metric in ("taxicab", "chessboard"):
            w = sp.distance_transform_cdt(a, metric=metric)
            g, rows[f"cdt_{metric}"] = timed(lambda: vf.distance_transform_cdt(a, metric=metric),
                                             args.repeat)
            assert np.array_equal(g, w), f"cdt {metric} differs from SciPy"
    rows["load_after"] = load()
    json.dump(rows, sys.stdout)


def parent(args):
    from scipy import ndimage as sp

    builds = []
    commits = {}
    for b in args.build or []:
        label, _, spec = b.partition("=")
        path, _, commit = spec.partition("@")
        builds.append((label, os.path.abspath(path)))
        if commit:
            commits[label] = commit
    if not builds:
        builds = [("voxfield", "")]
    env = dict(os.environ)
    if "VOXFIELD_DEVICE" not in env:
        env["VOXFIELD_DEVICE"] = "cpu"
    probe_env = dict(env)
    if builds[0][1]:
        probe_env["PYTHONPATH"] = builds[0][1]
    device = json.loads(subprocess.run(
        [sys.executable, "-c",
         "import json, os, voxfield; k = os.environ['VOXFIELD_DEVICE']; "
         "d = voxfield.devices(); "
         "print(json.dumps(next((x for x in d if x['type'] == k or str(x['index']) == k), "
         "d[0])))"],
        env=probe_env, capture_output=True, text=True, check=True).stdout)
    worlds = WORLDS if args.worlds == "all" else args.worlds.split(",")
    result = {"device": device, "date": datetime.datetime.now(datetime.timezone.utc).isoformat(),
              "commit": git_commit(REPO), "size": args.size, "seed": args.seed,
              "repeat": args.repeat, "index_repeat": args.index_repeat,
              "scipy_repeat": args.scipy_repeat, "cpus": os.cpu_count(),
              "builds": {label: path or "(this process's voxfield)" for label, path in builds},
              "worlds": []}
    for name in worlds:
        a = make_named(name, args.size, args.seed) == 0
        entry = {"world": name, "shape": list(a.shape), "load_before": load()}
        with tempfile.TemporaryDirectory(prefix="ndimage_vs_scipy_") as tmp:
            dt, entry["scipy_edt"] = timed(lambda: sp.distance_transform_edt(a),
                                           args.scipy_repeat, warmup=0)
            np.save(os.path.join(tmp, "edt.npy"), dt)
            del dt
            (_, ft), entry["scipy_indices"] = timed(
                lambda: sp.distance_transform_edt(a, return_indices=True), args.scipy_repeat,
                warmup=0)
            np.save(os.path.join(tmp, "ft.npy"), ft)
            del ft
            entry["builds"] = {}
            for label, path in builds:
                child_env = dict(env)
                if path:
                    child_env["PYTHONPATH"] = path
                if label in commits:
                    child_env["VOXFIELD_COMMIT"] = commits[label]
                cmd = [sys.executable, os.path.abspath(__file__), "--child", "--world", name,
                       "--size", str(args.size), "--seed", str(args.seed), "--repeat",
                       str(args.repeat), "--index-repeat", str(args.index_repeat),
                       "--scipy-dir", tmp] + (["--cdt"] if args.cdt else [])
                run = subprocess.run(cmd, env=child_env, capture_output=True, text=True)
                if run.returncode != 0:
                    sys.stderr.write(run.stderr)
                    raise SystemExit(f"{label} on {name}: the check or the run failed")
                rows = json.loads(run.stdout)
                for case, scipy_case in (("edt", "scipy_edt"), ("edt_out", "scipy_edt"),
                                         ("indices", "scipy_indices")):
                    rows[case]["speedup"] = (entry[scipy_case]["median_ms"] /
                                             rows[case]["median_ms"])
                    rows[case]["cpu_speedup"] = (entry[scipy_case]["cpu_median_ms"] /
                                                 rows[case]["cpu_median_ms"])
                entry["builds"][label] = rows
        entry["load_after"] = load()
        result["worlds"].append(entry)
        line = " ".join(
            f"{label}: edt {r['edt']['median_ms']:.0f} ms x{r['edt']['speedup']:.1f} "
            f"(CPU x{r['edt']['cpu_speedup']:.1f}), "
            f"out x{r['edt_out']['speedup']:.1f}, indices {r['indices']['median_ms']:.0f} ms "
            f"x{r['indices']['speedup']:.1f} (CPU x{r['indices']['cpu_speedup']:.1f});"
            for label, r in entry["builds"].items())
        print(f"{name:14s} SciPy edt {entry['scipy_edt']['median_ms']:.0f} ms, indices "
              f"{entry['scipy_indices']['median_ms']:.0f} ms; {line} load {entry['load_before']}",
              flush=True)
        if args.json:
            with open(args.json, "w") as f:
                json.dump(result, f, indent=1)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--size", type=int, default=256)
    p.add_argument("--repeat", type=int, default=5)
    p.add_argument("--index-repeat", type=int, default=3)
    p.add_argument("--scipy-repeat", type=int, default=1)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--worlds", default="all", help="comma-separated names of bench/worlds.py")
    p.add_argument("--build", action="append",
                   help="LABEL=PYTHONPATH[@COMMIT] of a voxfield build (repeatable; COMMIT "
                        "is recorded, else the module folder's git HEAD)")
    p.add_argument("--cdt", action="store_true", help="also distance_transform_cdt")
    p.add_argument("--json", default="")
    p.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    p.add_argument("--world", help=argparse.SUPPRESS)
    p.add_argument("--scipy-dir", help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.child:
        child(args)
    else:
        parent(args)


if __name__ == "__main__":
    main()
