#!/usr/bin/env python3
"""`voxfield generate` of two or more binaries on the benchmark worlds, interleaved, outputs compared.

Usage (on the machine that times them, e.g. a GPU host with binaries packed by bench/bundle.sh):
    python3 bench/ab_generate.py --bin base=.gpu/bin/base --bin new=.gpu/bin/new \\
        --size 512 --worlds all --cases l2-f32,l2-indices --device gpu --rounds 2 \\
        --tmpdir /dev/shm --json bench/results/h200-ab-COMMIT.json

A binary is LABEL=PATH, optionally followed by environment variables for its runs,
LABEL=PATH,VAR=VALUE,... (an experiment's switch in an uncommitted build). For each world of
bench/worlds.py (--worlds, N^3 voxels, seeded; 'all' for the whole set) and each case of --cases
(CASES below: metric, format and whether index planes are written), the binaries run one after
the other, --rounds times, so that a machine's drift falls on all of them alike: each
`voxfield generate WORLD.npy -o F.npy [--indices I.npy] OPTIONS --device D --warmup W --repeat R
--json J`. Kept per run: every kernel time (OpenCL profiling events) and each stage's median.
The outputs of the first round (field, and index planes) are compared byte for byte with the
first binary's: a change that should not move a value must say `equal`. Prints a line per world
and case (median kernel time over all samples of all rounds, its range, and the ratio to the
first binary) and writes everything, with each run's device and commit, to --json after each
world.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
import zlib

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from worlds import WORLDS, make_named  # noqa: E402

# Case name -> (generate options, whether it writes index planes).
CASES = {
    "l1-u16": (["--metric", "manhattan", "--format", "u16"], False),
    "l1-u8": (["--metric", "manhattan", "--format", "u8"], False),
    "linf-u16": (["--metric", "chebyshev", "--format", "u16"], False),
    "l2-f32": (["--metric", "euclidean", "--format", "f32"], False),
    "l2-indices": (["--metric", "euclidean", "--format", "f32"], True),
    "l1-indices": (["--metric", "manhattan", "--format", "u16"], True),
    "l2-signed": (["--metric", "euclidean", "--format", "f32", "--signed"], False),
    "l1-signed": (["--metric", "manhattan", "--format", "i16", "--signed"], False),
    "l2-spacing": (["--metric", "euclidean", "--format", "f32", "--spacing", "1.5,0.75,2"], False),
}


def parse_bin(spec):
    """LABEL=PATH[,VAR=VALUE...] -> (label, path, env)."""
    label, sep, rest = spec.partition("=")
    if not sep or not label or not rest:
        sys.exit(f"ab_generate: --bin {spec!r}: expected LABEL=PATH[,VAR=VALUE...]")
    path, *assignments = rest.split(",")
    env = {}
    for a in assignments:
        var, sep, value = a.partition("=")
        if not sep or not var:
            sys.exit(f"ab_generate: --bin {spec!r}: {a!r} is not VAR=VALUE")
        env[var] = value
    if not os.access(path, os.X_OK):
        sys.exit(f"ab_generate: --bin {spec!r}: {path} is not an executable")
    return label, path, env


def digest(paths):
    """crc32 of the files' bytes, in order, read 64 MiB at a time."""
    crc = 0
    for path in paths:
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 26), b""):
                crc = zlib.crc32(block, crc)
    return crc


def run(binary, world, case, args, tmp):
    label, path, env = binary
    options, indices = CASES[case]
    field = os.path.join(tmp, f"field-{label}.npy")
    idx = os.path.join(tmp, f"indices-{label}.npy")
    js = os.path.join(tmp, f"run-{label}.json")
    cmd = [path, "generate", world, "-o", field, *options, "--device", args.device,
           "--warmup", str(args.warmup), "--repeat", str(args.repeat), "--json", js]
    if indices:
        cmd += ["--indices", idx]
    proc = subprocess.run(cmd, capture_output=True, text=True, env={**os.environ, **env})
    if proc.returncode != 0:
        sys.stderr.write(proc.stdout + proc.stderr)
        sys.exit(f"ab_generate: {' '.join(cmd)} failed ({proc.returncode})")
    with open(js) as f:
        doc = json.load(f)
    return doc, [field, idx] if indices else [field]


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter,
                                epilog="\n".join(__doc__.split("\n")[1:]))
    p.add_argument("--bin", action="append", required=True,
                   help="LABEL=PATH[,VAR=VALUE...] (two or more; the first is the reference)")
    p.add_argument("--size", type=int, default=256, help="world edge N (default 256)")
    p.add_argument("--seed", type=int, default=1, help="world seed (default 1)")
    p.add_argument("--worlds", default="all",
                   help="comma-separated worlds of bench/worlds.py, or 'all' (default)")
    p.add_argument("--cases", default="l2-f32",
                   help=f"comma-separated cases of {','.join(CASES)} (default l2-f32)")
    p.add_argument("--device", default="gpu", help="voxfield --device (default gpu)")
    p.add_argument("--warmup", type=int, default=2, help="untimed runs per process (default 2)")
    p.add_argument("--repeat", type=int, default=8, help="timed runs per process (default 8)")
    p.add_argument("--rounds", type=int, default=2, help="processes per binary (default 2)")
    p.add_argument("--tmpdir", help="folder for the world and outputs (default: the system's)")
    p.add_argument("--json", default="", help="write every sample and stage to this file")
    args = p.parse_args()
    bins = [parse_bin(b) for b in args.bin]
    if len(bins) < 2:
        sys.exit("ab_generate: give two or more --bin")
    if len({b[0] for b in bins}) != len(bins):
        sys.exit("ab_generate: the --bin labels must differ")
    names = WORLDS if args.worlds == "all" else args.worlds.split(",")
    cases = args.cases.split(",")
    for name in names:
        if name not in WORLDS:
            sys.exit(f"ab_generate: unknown world {name!r} (bench/worlds.py: {','.join(WORLDS)})")
    for case in cases:
        if case not in CASES:
            sys.exit(f"ab_generate: unknown case {case!r} ({','.join(CASES)})")
    if args.rounds < 1 or args.repeat < 1 or args.warmup < 0:
        sys.exit("ab_generate: --rounds and --repeat must be positive, --warmup not negative")
    report = {"date": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()), "size": args.size,
              "seed": args.seed, "device_arg": args.device, "warmup": args.warmup,
              "repeat": args.repeat, "rounds": args.rounds,
              "binaries": {label: {"path": path, "env": env} for label, path, env in bins},
              "worlds": {}}
    ref = bins[0][0]
    with tempfile.TemporaryDirectory(prefix="vf_ab_", dir=args.tmpdir) as tmp:
        for name in names:
            world = os.path.join(tmp, "world.npy")
            np.save(world, make_named(name, args.size, args.seed))
            entry = report["worlds"].setdefault(name, {})
            for case in cases:
                rows = {b[0]: {"kernel_ms": [], "stages": [], "device": None, "commit": None}
                        for b in bins}
                load = os.getloadavg()[0]
                for r in range(args.rounds):
                    for binary in bins:
                        doc, files = run(binary, world, case, args, tmp)
                        row = rows[binary[0]]
                        row["kernel_ms"] += doc["kernel_ms_samples"]
                        row["stages"].append({s["kernel"]: s["median_ms"] for s in doc["stages"]})
                        row["device"], row["commit"] = doc.get("device"), doc.get("commit")
                        if r == 0:
                            row["digest"] = digest(files)
                for label, row in rows.items():
                    row["median_ms"] = statistics.median(row["kernel_ms"])
                    row["equal"] = row["digest"] == rows[ref]["digest"]
                entry[case] = {"load": load, "runs": rows}
                base = rows[ref]["median_ms"]
                print(f"{name:14s} {case:11s} " + "  ".join(
                    f"{label} {row['median_ms']:.3f} ms ({min(row['kernel_ms']):.3f}-"
                    f"{max(row['kernel_ms']):.3f})"
                    + ("" if label == ref else
                       f" {row['median_ms'] / base:.3f}x"
                       f" {'equal' if row['equal'] else 'DIFFERENT'}")
                    for label, row in rows.items()) + f"  load {load:.2f}", flush=True)
            if args.json:
                with open(args.json, "w") as f:
                    json.dump(report, f, indent=1)


if __name__ == "__main__":
    main()
