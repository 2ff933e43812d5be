#!/usr/bin/env python3
"""Prints the result tables of bench/README.md from committed JSON files.

Usage: python3 bench/summarize.py FILES...
`voxfield bench --json` files give the timing table; `compare_scipy.py --json` files give the
SciPy comparison table; `voxfield replay --json` files give the incremental-update table. Files of neither kind are skipped.
"""
import json
import sys


def bench_rows(path, doc):
    device = doc["device"]["name"]
    for r in doc["results"]:
        size = "x".join(str(v) for v in r["size"])
        algorithm = r.get("algorithm", "exact")
        chunk = r.get("chunk") or "-"
        head = f"| {device} | {doc['commit'][:8]} | {doc['date'][:10]} | {algorithm} | {size} | {chunk} |"
        if "skipped" in r:
            yield head + f" skipped: {r['skipped']} |" + " |" * 9
            continue
        lo, hi = r["ci95_ms"]
        stages = ", ".join(f"{s['kernel']} {s['median_ms']:.3f}" for s in r.get("stages", []))
        iterations = r.get("iterations") or "-"
        over = 100 * r.get("over_fraction", 0)
        yield (head + f" {r['format']} | {r['median_ms']:.3f} | {lo:.3f}-{hi:.3f} |"
               f" {r['gvox_per_s']:.2f} | {iterations} | {r['max_error']} |"
               f" {r['mean_error']:.4f} | {over:.3f} | {stages} |")


def scipy_row(path, doc):
    return (f"| {doc['device']} | {doc['commit'][:8]} | {doc['date'][:10]} |"
            f" {'x'.join(str(v) for v in doc['size'])} | {doc['ours_kernel_ms_median']:.2f} |"
            f" {doc['scipy_ms_median']:.1f} | {doc['ratio_scipy_over_ours_kernel']:.1f} |"
            f" {doc['equal']} | `{path}` |")


def replay_row(path, doc):
    sm = doc["summary"]
    return (f"| `{path.split('/')[-1]}` | {sm['median_update_ms']:.3f} | {sm['mean_update_ms']:.3f} |"
            f" {sm['max_update_ms']:.3f} | {doc['full_regeneration_ms']:.3f} |"
            f" {sm['ratio_full_to_median_update']:.1f} | {sm['voxels_recomputed'] / sm['edits']:.0f} |")


def main(paths):
    bench, scipy, replay = [], [], []
    for path in paths:
        with open(path) as f:
            doc = json.load(f)
        if "results" in doc:
            bench.extend(bench_rows(path, doc))
        elif "scipy_ms_median" in doc:
            scipy.append(scipy_row(path, doc))
        elif "full_regeneration_ms" in doc:
            replay.append(replay_row(path, doc))
    if bench:
        print("| device | commit | date | algorithm | size | chunk | format | median ms |"
              " 95% CI ms | Gvox/s | FIM passes | max error | mean error | over-estimated % |"
              " per kernel (median ms) |")
        print("| --- | --- | --- | --- | --- | --- | --- | ---: | --- | ---: | ---: | ---: | ---: |"
              " ---: | --- |")
        print("\n".join(bench))
    if scipy:
        if bench:
            print()
        print("| device | commit | date | size | ours kernel median ms | SciPy cdt median ms |"
              " SciPy / ours | outputs equal | file |")
        print("| --- | --- | --- | --- | ---: | ---: | ---: | --- | --- |")
        print("\n".join(scipy))
    if replay:
        if bench or scipy:
            print()
        print("| file | median update ms | mean | max | full regeneration ms | full / median |"
              " voxels recomputed per edit |")
        print("| --- | ---: | ---: | ---: | ---: | ---: | ---: |")
        print("\n".join(replay))


if __name__ == "__main__":
    main(sys.argv[1:])
