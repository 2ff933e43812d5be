#!/usr/bin/env python3
"""`voxfield generate` end to end (read, compute, write) against SciPy and against streaming its bytes.

Usage: /usr/bin/python3 bench/endtoend.py [--voxfield build/viewer/voxfield] [--size 512]
           [--repeat 5] [--device cpu] [--format u16] [--metric manhattan] [--peer scipy]
           [--workdir DIR] [--json OUT.json]

In one run: writes the N^3 floor-and-spheres world (uint8 .npy, `bench/make_edits.py --size N
--edits 0`, the world of the README's 512^3 render benchmark), warms the page cache and the
kernel cache (one untimed generate), then repeats R rounds of, in turn:
  (a) `voxfield generate W -o F --device D --format F`: the wall time of the process and its peak
      RSS (getrusage of the child);
  (b) the peer in one Python process: np.load + the peer's transform + np.save of what it
      returns: SciPy's distance_transform_cdt(taxicab) (int32) for --metric manhattan,
      cdt(chessboard) for chebyshev, distance_transform_edt (float64) for euclidean, or with
      --peer cupy (euclidean only) cupyx.scipy.ndimage.distance_transform_edt, its input
      uploaded and its float64 result downloaded; the time of those calls (interpreter start
      and imports excluded, CuPy's first-call kernel compilation included) and the process's
      wall time;
  (c) streaming: reading the input file and writing as many bytes as generate's output to a file,
      through one reused 1 MiB buffer (what `cat` does), in this process.
One more generate with --json records the device and generate's phases. It prints medians,
spreads and the ratios of DESIGN §5's target (generate >= 4x faster than (b), <= 5x (c), peak
RSS <= input + output + 1 byte per voxel) and issue 26's (on a GPU: generate <= 2x (c) and >= 3x
the CuPy process), checks that generate's field equals the peer's (Euclidean: within one
float32 ulp of its float64), and
writes everything to --json with device, date and commit. Exit status: 0 when the run worked
(targets are reported, not asserted), 1 if the fields differ, 2 on bad usage or a failed run.
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

from repo import REPO, git_commit  # noqa: E402

PEER_JOB = r"""
import json, sys, time
t0 = time.perf_counter()
import numpy as np
peer, metric = sys.argv[3], sys.argv[4]
if peer == "cupy":
    import cupy as cp
    from cupyx.scipy import ndimage
else:
    from scipy import ndimage
t1 = time.perf_counter()
world = np.load(sys.argv[1])
if peer == "cupy":
    field = cp.asnumpy(ndimage.distance_transform_edt(cp.asarray(world) == 0))
elif metric == "euclidean":
    field = ndimage.distance_transform_edt(world == 0)
else:
    field = ndimage.distance_transform_cdt(
        world == 0, metric="taxicab" if metric == "manhattan" else "chessboard")
np.save(sys.argv[2], field)
t2 = time.perf_counter()
print(json.dumps({"import_s": t1 - t0, "job_s": t2 - t1}))
"""


def fields_agree(ours, peer, metric):
    """Equal (L1, L-inf), or within one float32 ulp of the peer's float64 (L2)."""
    if metric != "euclidean":
        return bool(np.array_equal(ours, peer))
    ulp = np.spacing(peer.astype(np.float32)).astype(np.float64)
    return bool(np.all(np.abs(ours.astype(np.float64) - peer) <= ulp))


def spread(samples):
    return {"median": statistics.median(samples), "min": min(samples), "max": max(samples),
            "samples": samples}


def run_child(args, log):
    """(wall seconds, peak RSS bytes) of one child process; exits 2 when it fails."""
    with open(log, "w") as out:
        t0 = time.perf_counter()
        p = subprocess.Popen(args, stdout=out, stderr=subprocess.STDOUT)
        _, status, usage = os.wait4(p.pid, 0)
        wall = time.perf_counter() - t0
    p.returncode = os.waitstatus_to_exitcode(status)
    if p.returncode != 0:
        with open(log) as f:
            sys.stderr.write(f"endtoend: {' '.join(args)} failed ({p.returncode}):\n{f.read()}")
        sys.exit(2)
    return wall, usage.ru_maxrss * 1024


def stream(src, dst, out_bytes, buf):
    """Seconds to read `src` and write `out_bytes` to `dst` through `buf` (a reused buffer)."""
    view = memoryview(buf)
    t0 = time.perf_counter()
    with open(src, "rb", buffering=0) as f:
        while f.readinto(buf):
            pass
    with open(dst, "wb", buffering=0) as g:
        left = out_bytes
        while left > 0:
            left -= g.write(view[:min(left, len(buf))])
    return time.perf_counter() - t0


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--voxfield", default=os.path.join(REPO, "build", "viewer", "voxfield"))
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--format", default="u16", choices=["u8", "u16", "u32", "f32"])
    ap.add_argument("--metric", default="manhattan",
                    choices=["manhattan", "chebyshev", "euclidean"])
    ap.add_argument("--peer", default="scipy", choices=["scipy", "cupy"])
    ap.add_argument("--workdir", help="folder for the world and the outputs (default: a "
                    "temporary folder, removed afterwards)")
    ap.add_argument("--json", help="write the results here")
    a = ap.parse_args()
    if a.size < 1 or a.repeat < 3:
        ap.error("--size must be at least 1 and --repeat at least 3")
    if a.peer == "cupy" and a.metric != "euclidean":
        ap.error("--peer cupy has only the Euclidean transform (distance_transform_edt)")
    if not os.access(a.voxfield, os.X_OK):
        ap.error(f"{a.voxfield} is not an executable (build voxfield or pass --voxfield)")

    with tempfile.TemporaryDirectory(dir=a.workdir) as tmp:
        world = os.path.join(tmp, "world.npy")
        field = os.path.join(tmp, "field.npy")
        scipy_field = os.path.join(tmp, "scipy.npy")
        streamed = os.path.join(tmp, "stream.bin")
        log = os.path.join(tmp, "log.txt")
        subprocess.run([sys.executable, os.path.join(REPO, "bench", "make_edits.py"), "--size",
                        str(a.size), "--edits", "0", "--world", world, "--out",
                        os.path.join(tmp, "edits.txt")], check=True)
        generate = [a.voxfield, "generate", world, "-o", field, "--device", a.device,
                    "--format", a.format, "--metric", a.metric]
        voxels = a.size ** 3
        in_bytes = os.path.getsize(world)
        buf = bytearray(1 << 20)
        # Warm-up: the world in the page cache, the kernels in the kernel cache, every output
        # file once.
        run_child(generate, log)
        out_bytes = os.path.getsize(field)
        stream(world, streamed, out_bytes, buf)

        gen_s, gen_rss, scipy_job_s, scipy_proc_s, stream_s = [], [], [], [], []
        for _ in range(a.repeat):
            wall, rss = run_child(generate, log)
            gen_s.append(wall)
            gen_rss.append(rss)
            t0 = time.perf_counter()
            out = subprocess.run([sys.executable, "-c", PEER_JOB, world, scipy_field, a.peer,
                                  a.metric],
                                 check=True, capture_output=True, text=True)
            scipy_proc_s.append(time.perf_counter() - t0)
            scipy_job_s.append(json.loads(out.stdout)["job_s"])
            stream_s.append(stream(world, streamed, out_bytes, buf))

        record = os.path.join(tmp, "generate.json")
        run_child(generate + ["--json", record], log)
        with open(record) as f:
            j = json.load(f)

        equal = fields_agree(np.load(field), np.load(scipy_field), a.metric)

    g, s, c = statistics.median(gen_s), statistics.median(scipy_job_s), statistics.median(stream_s)
    rss = max(gen_rss)
    rss_limit = in_bytes + out_bytes + voxels
    phases = j.get("phases_ms", {})
    print(f"device: {j['device']['name']} ({j['device'].get('platform', '')}); world "
          f"{a.size}^3 floor + spheres, {in_bytes} bytes in, {out_bytes} bytes out ({a.format})")

    def line(name, samples):
        m = spread(samples)
        print(f"  {name:<44} median {m['median']:.3f} s (min {m['min']:.3f}, max {m['max']:.3f})")

    line("(a) voxfield generate, process wall", gen_s)
    peer_name = {"scipy": "SciPy", "cupy": "CuPy"}[a.peer]
    line(f"(b) {peer_name} load + transform + save", scipy_job_s)
    line(f"    {peer_name}, the whole process", scipy_proc_s)
    line("(c) streaming the same bytes (cat-like)", stream_s)
    if phases:
        order = ["read", "setup", "upload", "kernels", "download", "write", "wall"]
        print("  generate's phases (ms, read beside setup): " +
              ", ".join(f"{k} {phases[k]:.1f}" for k in order if k in phases))
    p = statistics.median(scipy_proc_s)
    print(f"  {peer_name} / generate: {s / g:.2f}x (its process: {p / g:.2f}x); generate / "
          f"streaming: {g / c:.2f}x")
    print(f"  peak RSS of generate: {rss} bytes = {rss / voxels:.2f} bytes/voxel (target <= "
          f"{rss_limit / voxels:.2f}: input + output + 1 per voxel)")
    print(f"  fields equal: {equal}")

    if a.json:
        result = {
            "device": j["device"],
            "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
            "commit": git_commit(),
            "voxfield_commit": j.get("commit"),
            "command": " ".join(["voxfield"] + generate[1:]),
            "size": [a.size, a.size, a.size],
            "format": a.format,
            "metric": a.metric,
            "peer": a.peer,
            "input_bytes": in_bytes,
            "output_bytes": out_bytes,
            "repeat": a.repeat,
            "generate_wall_s": spread(gen_s),
            "generate_peak_rss_bytes": gen_rss,
            "generate_phases_ms": phases,
            "scipy_job_s": spread(scipy_job_s),
            "scipy_process_s": spread(scipy_proc_s),
            "stream_s": spread(stream_s),
            "scipy_over_generate": s / g,
            "peer_process_over_generate": p / g,
            "generate_over_stream": g / c,
            "peak_rss_bytes_per_voxel": rss / voxels,
            "peak_rss_limit_bytes": rss_limit,
            "fields_equal": equal,
        }
        with open(a.json, "w") as f:
            json.dump(result, f, indent=2)
            f.write("\n")
    return 0 if equal else 1


if __name__ == "__main__":
    sys.exit(main())
