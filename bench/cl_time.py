#!/usr/bin/python3
"""Where a sparse edit's host time goes, from bench/cl_time.c's trace (LD_PRELOAD).

Each edit is a window of OpenCL calls: back from its kernel encode_count to the first call after
the previous wait (or after a pause of --gap microseconds without calls), on to the next
clWaitForEvents. Prints, over the windows, the median count and host microseconds per call kind,
the median sum of the calls' times and of the window's span (first call's start to the wait's
return).
    python3 bench/cl_time.py time.log [--gap 40]
"""
import argparse
import statistics
import sys
from collections import defaultdict


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("log")
    ap.add_argument("--gap", type=float, default=40.0, help="microseconds without calls that "
                    "start a window (default 40)")
    a = ap.parse_args()
    calls = []
    with open(a.log, errors="replace") as f:
        for line in f:
            if line.startswith("@@T "):
                _, name, start, ns = line.split()
                calls.append((name, int(start), int(ns)))
    windows = []
    for i, (name, _, _) in enumerate(calls):
        if name != "kernel:encode_count":
            continue
        s = i
        while s > 0:
            prev, ps, pn = calls[s - 1]
            if prev in ("waitevents", "finish") or calls[s][1] - (ps + pn) > a.gap * 1000:
                break
            s -= 1
        e = i
        while e < len(calls) and calls[e][0] != "waitevents":
            e += 1
        if e < len(calls):
            windows.append(calls[s:e + 1])
    if not windows:
        sys.exit("cl_time.py: no edit windows (no kernel:encode_count followed by a wait)")
    kinds = sorted({c[0] for w in windows for c in w})
    print("%d edit windows; per window, median over windows:" % len(windows))
    print("%-28s %7s %10s %10s" % ("call", "count", "host us", "us/call"))
    for k in kinds:
        counts = [sum(1 for c in w if c[0] == k) for w in windows]
        times = [sum(c[2] for c in w if c[0] == k) / 1000 for w in windows]
        n = statistics.median(counts)
        t = statistics.median(times)
        print("%-28s %7.1f %10.2f %10.2f" % (k, n, t, t / n if n else 0))
    inside = [sum(c[2] for c in w) / 1000 for w in windows]
    wait = [sum(c[2] for c in w if c[0] == "waitevents") / 1000 for w in windows]
    span = [(w[-1][1] + w[-1][2] - w[0][1]) / 1000 for w in windows]
    print("calls' time %.2f us (of it the wait %.2f), window span %.2f us: %.2f us between calls"
          % (statistics.median(inside), statistics.median(wait), statistics.median(span),
             statistics.median([s - t for s, t in zip(span, inside)])))


if __name__ == "__main__":
    main()
