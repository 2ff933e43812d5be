#!/usr/bin/env python3
"""Draws PNG plots from `voxfield bench --json` files (plain bench and every --suite).

Usage: python3 bench/plot.py --out DIR FILES...

Writes into DIR, from whatever the files hold:
  time_vs_size.png         median generation time vs voxel count per algorithm (log-log),
                           one panel per device; error bars are the 95% CI of the mean
  speedup_exact.png        median time of each dissertation method / median time of `exact`
                           on the same world in the same run (dissertation suite: per table)
  accuracy.png             max and mean error of each approximate method (against the exact
                           field of the row's semantics)
  edit_time_vs_size.png    edits suite: per-edit update time vs brush size, per algorithm
  edit_time_hist.png       edits suite: histograms of per-edit update times
  sand_rate.png            sand suite: steps per second (1000 / (simulate + update) device ms) at
                           every step, per world and field
  sand_update_vs_changed.png  sand suite: each step's update time against the voxels it changed
Needs matplotlib (Debian: apt-get install python3-matplotlib). Skipped rows are not drawn.
"""
import argparse
import json
import os
import sys

try:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
except ImportError:
    sys.exit("plot.py: matplotlib is missing: apt-get install python3-matplotlib")


def load(paths):
    docs = []
    for p in paths:
        with open(p) as f:
            doc = json.load(f)
        if "results" not in doc:
            print(f"plot.py: {p}: not a `voxfield bench --json` file, skipped", file=sys.stderr)
            continue
        doc["_path"] = p
        docs.append(doc)
    return docs


def voxels(r):
    x, y, z = r["size"]
    return x * y * z


def timed(r):
    return "skipped" not in r and r.get("median_ms") is not None


def short_device(doc):
    name = doc["device"]["name"]
    return "PoCL " + name.split("-")[0] if doc["device"].get("platform", "").startswith("Portable") \
        else name


def series_key(r, chunk=True):
    key = r["algorithm"]
    if r.get("chunk") and chunk:
        key += f" C={r['chunk']}"
    if r.get("focus"):
        key += f" focus {r['focus'][3]}"
    if r.get("table"):
        key = f"{r['table']}: {key}"
    return key


def plot_time_vs_size(docs, out):
    gen_docs = [d for d in docs if d.get("suite") != "edits" and any(timed(r) for r in d["results"])]
    if not gen_docs:
        return None
    fig, axes = plt.subplots(1, len(gen_docs), figsize=(7 * len(gen_docs), 5.5), squeeze=False)
    for ax, doc in zip(axes[0], gen_docs):
        series = {}
        for r in doc["results"]:
            if timed(r):
                # Suite rows: the table fixes how the chunk follows the size.
                series.setdefault(series_key(r, chunk="table" not in r), []).append(r)
        for key, rows in sorted(series.items()):
            rows.sort(key=voxels)
            xs = [voxels(r) for r in rows]
            ys = [r["median_ms"] for r in rows]
            lo = [max(0.0, r["median_ms"] - r["ci95_ms"][0]) for r in rows]
            hi = [max(0.0, r["ci95_ms"][1] - r["median_ms"]) for r in rows]
            ax.errorbar(xs, ys, yerr=[lo, hi], marker="o", ms=3, capsize=2, label=key)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("voxels")
        ax.set_ylabel("median time per generation (ms)")
        ax.set_title(f"{short_device(doc)} {doc.get('suite', 'bench')} ({doc['commit'][:8]})",
                     fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=6, ncol=2)
    fig.tight_layout()
    path = os.path.join(out, "time_vs_size.png")
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def speedups(doc):
    """(label, ratio) of each timed non-exact row over `exact` on the same world and group."""
    exact = {}
    for r in doc["results"]:
        if timed(r) and r["algorithm"] == "exact":
            exact[(r.get("table"), r.get("group"), tuple(r["size"]))] = r["median_ms"]
    out = []
    for r in doc["results"]:
        if not timed(r) or r["algorithm"] == "exact":
            continue
        e = exact.get((r.get("table"), r.get("group"), tuple(r["size"])))
        if e and e > 0:
            size = "x".join(str(v) for v in r["size"])
            out.append((f"{series_key(r)} {size}", r["median_ms"] / e))
    return out


def plot_speedup(docs, out):
    rows = []
    for doc in docs:
        if doc.get("suite") == "edits":
            continue
        rows += [(f"{short_device(doc)}: {k}", v) for k, v in speedups(doc)]
    if not rows:
        return None
    fig, ax = plt.subplots(figsize=(10, max(3, 0.22 * len(rows) + 1)))
    labels = [k for k, _ in rows]
    ax.barh(range(len(rows)), [v for _, v in rows])
    ax.set_yticks(range(len(rows)))
    ax.set_yticklabels(labels, fontsize=6)
    ax.invert_yaxis()
    ax.set_xscale("log")
    ax.axvline(1.0, color="k", lw=0.8)
    ax.set_xlabel("speed-up of exact (method median / exact median, same world, same run)")
    ax.grid(True, axis="x", which="both", alpha=0.3)
    fig.tight_layout()
    path = os.path.join(out, "speedup_exact.png")
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


APPROXIMATE = {"jfa", "jfa-host", "lod"}


def plot_accuracy(docs, out):
    rows = []
    for doc in docs:
        for r in doc["results"]:
            if timed(r) and r["algorithm"] in APPROXIMATE and r.get("max_error") is not None:
                size = "x".join(str(v) for v in r["size"])
                rows.append((f"{short_device(doc)}: {series_key(r)} {size}", r["max_error"],
                             r["mean_error"], 100 * r.get("over_fraction", 0)))
    if not rows:
        return None
    fig, axes = plt.subplots(1, 2, figsize=(12, max(3, 0.22 * len(rows) + 1)), sharey=True)
    ys = range(len(rows))
    axes[0].barh(ys, [r[1] for r in rows])
    axes[0].set_xlabel("max error (voxels)")
    axes[1].barh(ys, [r[3] for r in rows])
    axes[1].set_xlabel("over-estimated voxels (%)")
    axes[0].set_yticks(list(ys))
    axes[0].set_yticklabels([r[0] for r in rows], fontsize=6)
    axes[0].invert_yaxis()
    for ax in axes:
        ax.grid(True, axis="x", alpha=0.3)
    fig.suptitle("approximate methods against the exact field of their semantics", fontsize=9)
    fig.tight_layout()
    path = os.path.join(out, "accuracy.png")
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def edit_rows(docs):
    for doc in docs:
        if doc.get("suite") != "edits":
            continue
        for r in doc["results"]:
            if timed(r) and r.get("edits"):
                yield doc, r


def plot_edit_time_vs_size(docs, out):
    rows = list(edit_rows(docs))
    if not rows:
        return None
    fig, ax = plt.subplots(figsize=(8, 5.5))
    for doc, r in rows:
        by_size = {}
        for e in r["edits"]:
            by_size.setdefault(e["size"], []).append(e["update_ms"])
        sizes = sorted(by_size)
        med = [sorted(by_size[s])[len(by_size[s]) // 2] for s in sizes]
        ax.plot(sizes, med, marker="o", ms=3, label=f"{short_device(doc)}: {series_key(r)}")
    ax.set_yscale("log")
    ax.set_xlabel("brush size (1..C-1; radius = size / 2)")
    ax.set_ylabel("median update time per edit (ms)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=6)
    fig.tight_layout()
    path = os.path.join(out, "edit_time_vs_size.png")
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def plot_edit_hist(docs, out):
    rows = list(edit_rows(docs))
    if not rows:
        return None
    cols = 3
    lines = (len(rows) + cols - 1) // cols
    fig, axes = plt.subplots(lines, cols, figsize=(12, 2.8 * lines), squeeze=False)
    for ax, (doc, r) in zip(axes.flat, rows):
        ax.hist([e["update_ms"] for e in r["edits"]], bins=30)
        ax.set_title(f"{short_device(doc)}: {series_key(r)}", fontsize=8)
        ax.set_xlabel("update time (ms)", fontsize=7)
        ax.tick_params(labelsize=6)
    for ax in list(axes.flat)[len(rows):]:
        ax.axis("off")
    fig.tight_layout()
    path = os.path.join(out, "edit_time_hist.png")
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def sand_rows(docs):
    for doc in docs:
        for r in doc["results"]:
            if r.get("per_step"):
                bound = r.get("max_distance")
                size = "x".join(str(v) for v in r["size"])
                yield doc, r, f"{short_device(doc)} {size} L1" + (f" D={bound:g}" if bound else "")


def plot_sand_rate(docs, out):
    rows = list(sand_rows(docs))
    if not rows:
        return None
    fig, ax = plt.subplots(figsize=(8, 5))
    for doc, r, label in rows:
        steps = [s["step"] for s in r["per_step"]]
        rate = [1000.0 / max(s["simulate_ms"] + s["update_ms"], 1e-9) for s in r["per_step"]]
        ax.plot(steps, rate, lw=1, label=label)
    ax.set_yscale("log")
    ax.set_xlabel("step")
    ax.set_ylabel("steps per second (device time: simulate + field update)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    path = os.path.join(out, "sand_rate.png")
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def plot_sand_update_vs_changed(docs, out):
    rows = list(sand_rows(docs))
    if not rows:
        return None
    fig, ax = plt.subplots(figsize=(8, 5))
    for doc, r, label in rows:
        ax.scatter([s["voxels_changed"] for s in r["per_step"]],
                   [s["update_ms"] for s in r["per_step"]], s=6, label=label)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("voxels the step changed")
    ax.set_ylabel("field update (device ms)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    path = os.path.join(out, "sand_update_vs_changed.png")
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, help="folder for the PNG files (must exist)")
    ap.add_argument("files", nargs="+", help="voxfield bench --json files")
    a = ap.parse_args()
    if not os.path.isdir(a.out):
        ap.error(f"--out {a.out}: no such folder")
    docs = load(a.files)
    sand = [d for d in docs if d.get("suite") == "sand"]
    others = [d for d in docs if d.get("suite") != "sand"]
    written = []
    for fn, subset in ((plot_time_vs_size, others), (plot_speedup, others),
                       (plot_accuracy, others), (plot_edit_time_vs_size, others),
                       (plot_edit_hist, others), (plot_sand_rate, sand),
                       (plot_sand_update_vs_changed, sand)):
        p = fn(subset, a.out)
        if p:
            written.append(p)
    for p in written:
        print(f"wrote {p}")
    if not written:
        print("plot.py: nothing to plot (no timed rows)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
