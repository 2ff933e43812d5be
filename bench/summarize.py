#!/usr/bin/env python3
"""Prints the result tables of bench/README.md from committed JSON files.

Usage: python3 bench/summarize.py FILES...
`voxfield bench --json` files give the timing table; `compare_scipy.py --json` files give the
SciPy comparison table; `compare_cupy.py --json` files the CuPy one; `voxfield replay --json`
files give the incremental-update table; `voxfield bench --suite dissertation` files give one
table per dissertation table with its published numbers beside ours; `--suite edits` files the
editing-protocol table, `--suite render` files the ray-march table. Other files are skipped.
"""
import json
import sys

# The dissertation's published figures (RTX 3070 laptop GPU, Vulkan compute shaders), typed
# from ../shared/reference/dissertation-fast-gpu-distance-fields.txt and cited by table:
# {table: (column header, {edge: (mean ms, std ms or None, iterations or None)})}. Table 4.3
# gives the execution time per update of the edited chunks, not of the whole world.
PUBLISHED = {
    "Table 4.2": ("world", {8: (0.13085426, 0.07906039, None), 16: (0.72909933, 0.72129595, None),
                            32: (8.415086, 0.6034345, None), 64: (431.46756, 23.69193, None),
                            128: (25854.305, 43.82031, None)}),
    "Table 4.3": ("world", {32: (0.8090571, None, None), 64: (0.7992149, None, None),
                            128: (0.7797105, None, None), 256: (0.7632012, None, None),
                            512: (0.7504562, None, None)}),
    "Table 4.4": ("chunk", {8: (0.0408411, 0.012230597, 1.0313779),
                            16: (0.05089584, 0.009375835, 1.1514729),
                            32: (0.1566725, 0.07214462, 1.4801816),
                            64: (1.089782, 0.5198319, 2.3467271),
                            128: (17.556416, 16.088636, 6.194286)}),
    "Table 4.5": ("chunk", {8: (0.031079482, 0.0060166107, None),
                            16: (0.37563447, 0.0011396826, None),
                            32: (0.07390518, 0.014052732, None),
                            64: (0.38933817, 0.1003621, None), 128: (8.052377, 3.9264889, None)}),
    "Table 4.6": ("chunk", {8: (0.04326828, 0.014001529, 0.21335079),
                            16: (0.042948034, 0.0082087135, 0.41733277),
                            32: (0.142226286, 0.004889435, 0.9516885),
                            64: (0.8856182, 0.48032447, 1.2535588),
                            128: (16.556087, 13.672007, 4.1610336)}),
    "Table 4.7": ("chunk", {16: (0.023970172, 0.004594186, None),
                            32: (0.058316454, 0.013979476, None),
                            64: (0.29299217, 0.030013368, None), 128: (4.556905, 2.038477, None),
                            256: (29.263702, 20.3295, None)}),
    "Table 5.1": ("chunk", {16: (0.022988718, 0.00283882, None),
                            32: (0.057287574, 0.013250402, None),
                            64: (0.29529586, 0.036815774, None), 128: (4.571752, 1.7831647, None),
                            256: (29.337261, 18.889853, None)}),
}
TABLE_ORDER = ["Table 4.2", "Table 4.3", "Table 4.4", "Table 4.5", "Table 4.6", "Table 4.7",
               "Figure 4.8", "Table 5.1"]


def fmt(v, digits=3):
    return "-" if v is None else f"{v:.{digits}f}"


FIM_ALGORITHMS = {"fim", "fim-host", "jfa-fim", "lod", "monolithic"}


def rate(v):
    """Gvox/s: two decimals from 0.1 up, two significant digits below (never 0.00)."""
    return f"{v:.2f}" if not v or v >= 0.1 else f"{v:.2g}"


def iters(r):
    """FIM passes that changed the field; '-' for algorithms without FIM."""
    return r.get("iterations") if r["algorithm"] in FIM_ALGORITHMS else "-"


def dissertation_tables(docs):
    """One markdown table per dissertation table: published figures beside ours."""
    out = []
    for table in TABLE_ORDER:
        rows = []
        for path, doc in docs:
            device = doc["device"]["name"]
            exact = {}
            for r in doc["results"]:
                if r.get("table") == table and r["algorithm"] == "exact" and "skipped" not in r:
                    exact[r["group"]] = r["median_ms"]
            for r in doc["results"]:
                if r.get("table") != table or r["algorithm"] == "exact":
                    continue
                size = "x".join(str(v) for v in r["size"])
                column, published = PUBLISHED.get(table, ("world", {}))
                edge = r["size"][1] if column == "world" else r.get("chunk")
                pub = published.get(edge)
                pub_text = "-" if pub is None else fmt(pub[0], 4) + (
                    f" ± {pub[1]:.4f}" if pub[1] is not None else "")
                pub_iter = "-" if pub is None or pub[2] is None else f"{pub[2]:.2f}"
                focus = r.get("focus")
                name = r["algorithm"] + (f" (focus {focus[3]})" if focus else "")
                head = (f"| {device[:24]} | {doc['commit'][:8]} | {name} | {size} |"
                        f" {r.get('chunk') or '-'} | {r['format']} | {pub_text} | {pub_iter} |")
                if "skipped" in r:
                    rows.append(head + f" skipped: {r['skipped']} |" + " |" * 8)
                    continue
                lo, hi = r["ci95_ms"]
                e = exact.get(r["group"])
                speedup = "-" if not e else f"{r['median_ms'] / e:.1f}"
                note = f" ({r['runs']} runs: budget)" if "budget_truncated" in r else ""
                rows.append(head + f" {r['mean_ms']:.3f}{note} | {r['std_ms']:.3f} |"
                            f" {lo:.3f}-{hi:.3f} | {r['median_ms']:.3f} |"
                            f" {iters(r)} |"
                            f" {r['max_error']} / {r['mean_error']:.4f} /"
                            f" {100 * r['over_fraction']:.2f}% | {fmt(e)} | {speedup} |")
        if not rows:
            continue
        if out:
            out.append("")
        out.append(f"**{table}** (published: RTX 3070 laptop, dissertation {table}, mean ± std ms)")
        out.append("")
        out.append("| device | commit | ours | world | chunk | format | published ms |"
                   " published iterations | ours mean ms | std ms | 95% CI ms | median ms |"
                   " FIM passes | max err / mean err / over | exact median ms (same world) |"
                   " exact speed-up |")
        out.append("| --- | --- | --- | --- | --- | --- | ---: | ---: | ---: | ---: | --- | ---: |"
                   " ---: | --- | ---: | ---: |")
        out.extend(rows)
    return out


def edits_table(docs):
    out = ["| device | commit | algorithm | world | chunk | edits | median update ms | mean |"
           " std | 95% CI ms | min | max | full regeneration ms | full / median |"
           " voxels recomputed per edit | max err after edits |",
           "| --- | --- | --- | --- | --- | ---: | ---: | ---: | ---: | --- | ---: | ---: | ---: |"
           " ---: | ---: | ---: |"]
    for path, doc in docs:
        for r in doc["results"]:
            size = "x".join(str(v) for v in r["size"])
            head = (f"| {doc['device']['name'][:24]} | {doc['commit'][:8]} | {r['algorithm']} |"
                    f" {size} | {r.get('chunk') or '-'} |")
            if "skipped" in r:
                out.append(head + f" skipped: {r['skipped']} |" + " |" * 10)
                continue
            lo, hi = r["ci95_ms"]
            ratio = r.get("ratio_full_to_median_update")
            out.append(head + f" {r['edits_done']} | {r['median_ms']:.3f} | {r['mean_ms']:.3f} |"
                       f" {r['std_ms']:.3f} | {lo:.3f}-{hi:.3f} | {r['min_ms']:.3f} |"
                       f" {r['max_ms']:.3f} | {r['full_regeneration_ms']:.3f} |"
                       f" {fmt(ratio, 1)} | {r['voxels_recomputed_mean']:.0f} | {r['max_error']} |")
    return out


def cupy_row(path, doc):
    return (f"| {doc['device']} | {doc['cupy_device']} | {doc['commit'][:8]} | {doc['date'][:10]} |"
            f" {'x'.join(str(v) for v in doc['size'])} | {doc['ours_kernel_ms_median']:.3f} |"
            f" {doc['cupy_edt_ms_median']:.3f} | {fmt(doc.get('cupy_edt_f32_ms_median'))} |"
            f" {doc['ratio_cupy_over_ours_kernel']:.2f} | {doc['bounds_l1_vs_edt_hold']} |"
            f" {doc['cupy_vs_scipy_edt']} | `{path}` |")


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
               f" {rate(r['gvox_per_s'])} | {iterations} | {r['max_error']} |"
               f" {r['mean_error']:.4f} | {over:.3f} | {stages} |")


def scipy_row(path, doc):
    edt = doc.get("scipy_edt_ms_median")
    return (f"| {doc['device']} | {doc['commit'][:8]} | {doc['date'][:10]} |"
            f" {'x'.join(str(v) for v in doc['size'])} | {doc['ours_kernel_ms_median']:.2f} |"
            f" {doc['scipy_ms_median']:.1f} | {doc['ratio_scipy_over_ours_kernel']:.1f} |"
            f" {doc['equal']} | {fmt(edt, 1)} | `{path}` |")


def case_rows(path, doc):
    """One row per case of a compare_scipy.py file that compares every metric."""
    size = "x".join(str(v) for v in doc["size"])
    for c in doc["comparisons"]:
        module = c.get("module_ms")
        yield (f"| {doc['device']} | {doc['commit'][:8]} | {doc['date'][:10]} | {size} |"
               f" {c['case']} | {c['format']} | {c['kernel_ms']['median']:.2f} |"
               f" {c['command_wall_ms']['median']:.1f} | {fmt(module and module['median'], 1)} |"
               f" {c['scipy_ms']['median']:.1f} | {c['ratio_scipy_over_kernel']:.1f} |"
               f" {fmt(c.get('ratio_scipy_over_module'), 1)} | {c['check']} | `{path}` |")


def replay_row(path, doc):
    sm = doc["summary"]
    return (f"| `{path.split('/')[-1]}` | {sm['median_update_ms']:.3f} | {sm['mean_update_ms']:.3f} |"
            f" {sm['max_update_ms']:.3f} | {doc['full_regeneration_ms']:.3f} |"
            f" {sm['ratio_full_to_median_update']:.1f} | {sm['voxels_recomputed'] / sm['edits']:.0f} |")


def render_rows(doc):
    device = doc["device"]["name"]
    for r in doc["results"]:
        size = "x".join(str(v) for v in r["size"])
        lo, hi = r["ci95_ms"]
        yield (f"| {device} | {r['vulkan_device']} | {doc['commit'][:8]} | {doc['date'][:10]} | {size} |"
               f" {r['width']}x{r['height']} | {r['format']} | {r['runs']} | {r['median_ms']:.3f} |"
               f" {lo:.3f}-{hi:.3f} | {r['mrays_per_s']:.1f} |")


def main(paths):
    bench, scipy, replay, cupy, dissertation, edits, render = [], [], [], [], [], [], []
    cases = []
    for path in paths:
        with open(path) as f:
            doc = json.load(f)
        if doc.get("suite") == "dissertation":
            dissertation.append((path, doc))
        elif doc.get("suite") == "edits":
            edits.append((path, doc))
        elif doc.get("suite") == "render":
            render.extend(render_rows(doc))
        elif "cupy_edt_ms_median" in doc:
            cupy.append(cupy_row(path, doc))
        elif "results" in doc:
            bench.extend(bench_rows(path, doc))
        elif "scipy_ms_median" in doc:
            scipy.append(scipy_row(path, doc))
            if "comparisons" in doc:
                cases.extend(case_rows(path, doc))
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
              " SciPy / ours | outputs equal | SciPy EDT ms (Euclidean: another metric) | file |")
        print("| --- | --- | --- | --- | ---: | ---: | ---: | --- | ---: | --- |")
        print("\n".join(scipy))
    if replay:
        if bench or scipy:
            print()
        print("| file | median update ms | mean | max | full regeneration ms | full / median |"
              " voxels recomputed per edit |")
        print("| --- | ---: | ---: | ---: | ---: | ---: | ---: |")
        print("\n".join(replay))
    blocks = []
    if cases:
        blocks.append(["| device | commit | date | size | case | format | kernel ms | command ms |"
                       " module ms | SciPy ms | SciPy / kernel | SciPy / module | check | file |",
                       "| --- | --- | --- | --- | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: |"
                       " --- | --- |"] + cases)
    if cupy:
        blocks.append(["| ours on | CuPy on | commit | date | size | ours kernel median ms |"
                       " CuPy EDT f64 median ms | CuPy EDT f32 median ms | CuPy f64 / ours |"
                       " EDT <= L1 <= sqrt3 EDT | CuPy vs SciPy EDT | file |",
                       "| --- | --- | --- | --- | --- | ---: | ---: | ---: | ---: | --- | --- |"
                       " --- |"] + cupy)
    if dissertation:
        blocks.append(dissertation_tables(dissertation))
    if edits:
        blocks.append(edits_table(edits))
    if render:
        blocks.append(["| OpenCL device (field) | Vulkan device (ray march) | commit | date | world |"
                       " image | field | runs | median ms | 95% CI ms | Mrays/s |",
                       "| --- | --- | --- | --- | --- | --- | --- | ---: | ---: | --- | ---: |"]
                      + render)
    for block in blocks:
        if bench or scipy or replay or block is not blocks[0]:
            print()
        print("\n".join(block))


if __name__ == "__main__":
    main(sys.argv[1:])
