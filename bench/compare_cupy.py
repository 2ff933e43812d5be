#!/usr/bin/env python3
"""Compare voxfield's exact fields on an NVIDIA GPU with CuPy's distance_transform_edt (PBA+).

Usage (on the NVIDIA machine, after building voxfield):
    python3 bench/compare_cupy.py --sizes 512 1024 --voxfield build/viewer/voxfield --repeat 10 \
        --json 'bench/results/h200-vs-cupy-{size}.json'
    python3 bench/compare_cupy.py --size 256 --repeat 20 --json bench/results/h200-vs-cupy-256.json

--json PATH writes one file for the whole run; a PATH holding `{size}` writes one file per size
instead (each in the form bench/summarize.py tabulates). Every file holds the device
(nvidia-smi's name and driver where available, and `voxfield devices --json`), the date, the
voxfield binary's commit (`voxfield --version`) and every timing sample. --cases picks a subset.

In one run, on one machine, for each size N of --sizes (or the single --size):
  1. builds each world of --worlds (bench/worlds.py's set, seeded; default the floor + spheres
     world of compare_scipy.py, N^3) and saves it as .npy;
  2. runs `voxfield generate WORLD.npy --device gpu --warmup W --repeat R --json J` for each case
     and takes the median of the R kernel times (OpenCL profiling events), recording the
     end-to-end time its JSON gives as well:

     case               voxfield                          CuPy peer (mask = world == 0)
     manhattan          --metric manhattan, u16           edt(mask): another metric (timing only)
     euclidean          --metric euclidean, f32           edt(mask)
     chebyshev          --metric chebyshev, u16           none (CuPy has no chessboard transform)
     signed-euclidean   --signed --metric euclidean, f32  edt(~solid) - edt(solid), padded by one
                                                          empty voxel, cropped
     euclidean-indices  --metric euclidean --indices      edt(mask, return_distances=True,
                        (f32 field + int32 indices)          return_indices=True)
     euclidean-sampling --metric euclidean --spacing      edt(mask, sampling=(2.0, 0.75, 1.5))
                        1.5,0.75,2.0, f64                    (numpy's z, y, x order)

  3. times each CuPy peer on the GPU with CUDA events around each call, after W untimed
     warm-up calls, and takes the median of R calls (inputs on the GPU before timing; float64
     output as SciPy's, and float32 where CuPy supports float64_distances=False);
  4. checks the values on the GPU, z-slab by z-slab (outputs are read with
     np.load(mmap_mode="r"), so memory stays bounded at 1024^3):
       - euclidean, signed-euclidean, euclidean-sampling: |ours - CuPy float64| <= 2**-23 *
         |CuPy float64| at every voxel (within one float32 ulp);
       - euclidean-indices: the field as euclidean, and every index names a solid voxel whose
         distance from the voxel is the field's (to the same tolerance);
       - manhattan (L1; CuPy's EDT is L2, so not compared for equality): EDT <= L1 <= sqrt(3) EDT;
       - chebyshev (L-inf): EDT / sqrt(3) <= L-inf <= EDT at full size, and equality with SciPy's
         distance_transform_cdt(metric="chessboard") on a --check-size world if SciPy is
         importable (said so otherwise); the same on that world for manhattan ("taxicab");
       - CuPy's EDT against SciPy's distance_transform_edt on the --check-size world (to 1e-6);
  5. prints a table (case, N, voxfield ms, CuPy ms, CuPy / voxfield, check).

Needs numpy and CuPy (e.g. `pip install cupy-cuda12x`) with an NVIDIA GPU; fails with exit 2
and a message naming what is missing otherwise (SciPy is optional). Exit status: 0 if the
checks pass, 1 if one fails, 2 on bad usage, missing CuPy or a failed voxfield run.
"""

import argparse
import datetime
import json
import math
import os
import shutil
import statistics
import subprocess
import sys
import tempfile

CASES = ["manhattan", "euclidean", "chebyshev", "signed-euclidean", "euclidean-indices",
         "euclidean-sampling"]
SAMPLING_XYZ = (1.5, 0.75, 2.0)  # euclidean-sampling's --spacing (CuPy's sampling: z, y, x)
TOL = 2.0 ** -23          # relative tolerance of the float32 comparisons (one float32 ulp)
SLAB_VOXELS = 1 << 25     # voxels per z-slab uploaded for a check (32 Mi: bounded GPU memory)


def fail(message):
    sys.stderr.write(f"compare_cupy: {message}\n")
    sys.exit(2)


def progress(message):
    sys.stderr.write(f"compare_cupy: {message}\n")
    sys.stderr.flush()


try:
    import numpy as np
except ImportError:
    fail("numpy is missing (Debian: apt-get install python3-numpy)")

from repo import REPO, git_commit  # noqa: E402
from worlds import WORLDS, make_named, make_world  # noqa: E402  (needs numpy)


def import_cupy():
    try:
        import cupy as cp
        from cupyx.scipy import ndimage as cnd
    except ImportError as e:
        fail(f"CuPy is not installed ({e}); this comparison needs an NVIDIA GPU with CuPy, "
             "e.g. `pip install cupy-cuda12x` (it cannot run on the PoCL/CPU machine)")
    try:
        count = cp.cuda.runtime.getDeviceCount()
    except Exception as e:  # cupy raises CUDARuntimeError without a driver
        fail(f"CuPy finds no usable CUDA device ({e})")
    if count < 1:
        fail("CuPy finds no CUDA device")
    return cp, cnd


def import_scipy_ndimage():
    try:
        from scipy import ndimage
    except ImportError:
        return None
    return ndimage


# ---------------------------------------------------------------------------- the machine


def voxfield_version(exe):
    """The binary's commit from `voxfield --version` ("voxfield <commit>"), or None."""
    try:
        out = subprocess.run([exe, "--version"], capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.TimeoutExpired):
        return None, None
    text = (out.stdout or out.stderr).strip()
    words = text.split()
    return text, (words[-1] if words else None)


def voxfield_devices(exe):
    """`voxfield devices --json`, parsed (or {"error": ...})."""
    try:
        out = subprocess.run([exe, "devices", "--json"], capture_output=True, text=True,
                             timeout=120)
    except (OSError, subprocess.TimeoutExpired) as e:
        return {"error": str(e)}
    if out.returncode != 0:
        return {"error": f"exit {out.returncode}: {out.stderr.strip()}"}
    try:
        return json.loads(out.stdout)
    except ValueError as e:
        return {"error": f"unreadable JSON ({e})", "stdout": out.stdout}


def nvidia_smi():
    """nvidia-smi's GPUs (index, name, driver, memory), or None without it."""
    exe = shutil.which("nvidia-smi")
    if not exe:
        return None
    fields = ["index", "name", "driver_version", "memory.total", "uuid"]
    try:
        out = subprocess.run([exe, "--query-gpu=" + ",".join(fields), "--format=csv,noheader"],
                             capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.TimeoutExpired) as e:
        return {"error": str(e)}
    if out.returncode != 0:
        return {"error": f"exit {out.returncode}: {out.stderr.strip()}"}
    gpus = []
    for line in out.stdout.strip().splitlines():
        values = [v.strip() for v in line.split(",")]
        gpus.append(dict(zip(fields, values)))
    return gpus


# ---------------------------------------------------------------------------- timing


def spread(samples):
    if not samples:
        return None
    return {"median": statistics.median(samples), "min": min(samples), "max": max(samples),
            "std": statistics.stdev(samples) if len(samples) > 1 else 0.0, "samples": samples}


def time_cupy(cp, fn, warmup, repeat):
    """`repeat` CUDA-event timings of fn() (ms) after `warmup` untimed calls."""
    for _ in range(warmup):
        fn()
    cp.cuda.Device().synchronize()
    samples = []
    for _ in range(repeat):
        start, end = cp.cuda.Event(), cp.cuda.Event()
        start.record()
        fn()
        end.record()
        end.synchronize()
        samples.append(float(cp.cuda.get_elapsed_time(start, end)))
    return samples


def run_voxfield(exe, world_path, field_path, json_path, device, flags, warmup, repeat):
    cmd = [exe, "generate", world_path, "-o", field_path, "--json", json_path,
           "--warmup", str(warmup), "--repeat", str(repeat)] + flags
    if device:
        cmd += ["--device", device]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        sys.stderr.write(proc.stdout)
        sys.stderr.write(proc.stderr)
        fail(f"voxfield failed (exit {proc.returncode}): {' '.join(cmd)}")
    with open(json_path) as f:
        return json.load(f), cmd


# ---------------------------------------------------------------------------- checks (GPU, z-slabs)


def slabs(shape):
    step = max(1, SLAB_VOXELS // max(1, shape[1] * shape[2]))
    for z0 in range(0, shape[0], step):
        yield z0, min(shape[0], z0 + step)


def upload(cp, mm, z0, z1, axis=None):
    """Slab z0:z1 of a (possibly memory-mapped) host array, on the GPU."""
    part = mm[z0:z1] if axis is None else mm[axis, z0:z1]
    return cp.asarray(np.ascontiguousarray(part))


def host(x):
    """A Python number from a CuPy 0-d array, a NumPy scalar or a number."""
    return x.item() if hasattr(x, "item") else x


def first_bad(cp, bad, z0, *arrays):
    """(z, y, x) of the first True of a slab mask and the arrays' values there."""
    flat = int(host(cp.argmax(bad.ravel().astype(cp.int8))))
    z, y, x = (int(v) for v in np.unravel_index(flat, bad.shape))
    return (z + z0, y, x), [host(a[z, y, x]) for a in arrays]


def check_close(cp, ours, ref, what="CuPy"):
    """(ok, detail): |ours - ref| <= 2**-23 |ref| at every voxel (ref float64 on the GPU)."""
    if tuple(ours.shape) != tuple(ref.shape):
        return False, f"shape {ours.shape}, expected {ref.shape}"
    bad_total, worst_abs, worst_rel, first = 0, 0.0, 0.0, None
    for z0, z1 in slabs(ours.shape):
        o = upload(cp, ours, z0, z1).astype(cp.float64)
        r = ref[z0:z1].astype(cp.float64)
        err = cp.abs(o - r)
        bad = err > TOL * cp.abs(r)
        n = int(host(cp.count_nonzero(bad)))
        worst_abs = max(worst_abs, float(host(err.max())) if err.size else 0.0)
        # |ref| >= 1 wherever it is not 0 (unit spacing): the relative error without a division by 0
        worst_rel = max(worst_rel, float(host((err / cp.maximum(cp.abs(r), 1.0)).max()))
                        if err.size else 0.0)
        if n and first is None:
            first = first_bad(cp, bad, z0, o, r)
        bad_total += n
        del o, r, err, bad
    summary = f"max |diff| {worst_abs:.3g} ({worst_rel / TOL:.3g} x 2^-23 relative)"
    if bad_total == 0:
        return True, f"within 2^-23 relative of {what} float64; {summary}"
    (z, y, x), (o, r) = first
    return False, (f"{bad_total} voxels beyond 2^-23 relative of {what} float64; {summary}; "
                   f"first (z,y,x)=({z},{y},{x}): ours {o!r}, {what} {r!r}")


def check_bounds(cp, ours, edt, metric):
    """(ok, detail): EDT <= L1 <= sqrt3 EDT (manhattan) or EDT/sqrt3 <= Linf <= EDT (chebyshev)."""
    if tuple(ours.shape) != tuple(edt.shape):
        return False, f"shape {ours.shape}, expected {edt.shape}"
    s3, eps = math.sqrt(3.0), 1e-9
    bad_total, first = 0, None
    for z0, z1 in slabs(ours.shape):
        v = upload(cp, ours, z0, z1).astype(cp.float64)
        e = edt[z0:z1]
        if metric == "manhattan":
            bad = (v < e - eps) | (v > s3 * e + eps)
        else:
            bad = (v > e + eps) | (e > s3 * v + eps)
        n = int(host(cp.count_nonzero(bad)))
        if n and first is None:
            first = first_bad(cp, bad, z0, v, e)
        bad_total += n
        del v, bad
    text = ("EDT <= L1 <= sqrt(3) EDT" if metric == "manhattan"
            else "EDT / sqrt(3) <= L-inf <= EDT")
    if bad_total == 0:
        return True, f"{text} holds at every voxel"
    (z, y, x), (v, e) = first
    return False, (f"{text} VIOLATED at {bad_total} voxels; first (z,y,x)=({z},{y},{x}): "
                   f"ours {v!r}, EDT {e!r}")


def check_indices(cp, field, idx, mask_gpu):
    """(ok, detail): every index is in the world, names a solid voxel, at the field's distance."""
    shape = tuple(field.shape)
    if tuple(idx.shape) != (3,) + shape or idx.dtype != np.int32:
        return False, f"indices have shape {idx.shape} dtype {idx.dtype}, expected (3,)+{shape} int32"
    out_of_world = names_empty = far = 0
    first = None
    for z0, z1 in slabs(shape):
        iz, iy, ix = (upload(cp, idx, z0, z1, a) for a in range(3))
        inside = ((iz >= 0) & (iz < shape[0]) & (iy >= 0) & (iy < shape[1]) &
                  (ix >= 0) & (ix < shape[2]))
        n_out = int(inside.size) - int(host(cp.count_nonzero(inside)))
        empty = inside & mask_gpu[cp.clip(iz, 0, shape[0] - 1), cp.clip(iy, 0, shape[1] - 1),
                                  cp.clip(ix, 0, shape[2] - 1)]
        n_empty = int(host(cp.count_nonzero(empty)))
        zg = cp.arange(z0, z1, dtype=cp.int64).reshape(-1, 1, 1)
        yg = cp.arange(shape[1], dtype=cp.int64).reshape(1, -1, 1)
        xg = cp.arange(shape[2], dtype=cp.int64).reshape(1, 1, -1)
        d = cp.sqrt(((iz - zg) ** 2 + (iy - yg) ** 2 + (ix - xg) ** 2).astype(cp.float64))
        f = upload(cp, field, z0, z1).astype(cp.float64)
        wrong = inside & (cp.abs(f - d) > TOL * d)
        n_far = int(host(cp.count_nonzero(wrong)))
        if (n_out or n_empty or n_far) and first is None:
            first = first_bad(cp, ~inside | empty | wrong, z0, iz, iy, ix, f, d)
        out_of_world += n_out
        names_empty += n_empty
        far += n_far
        del iz, iy, ix, inside, empty, d, f, wrong
    if not (out_of_world or names_empty or far):
        return True, "every index names a solid voxel at the field's distance"
    (z, y, x), (a, b, c, f, d) = first
    return False, (f"indices: {out_of_world} outside the world, {names_empty} naming an empty "
                   f"voxel, {far} at another distance than the field's; first (z,y,x)=({z},{y},{x}): "
                   f"index ({a},{b},{c}), field {f!r}, its distance {d!r}")


def small_checks(args, cnd_pair, tmp):
    """On the --check-size world: CuPy EDT vs SciPy EDT, voxfield chebyshev/manhattan vs SciPy cdt."""
    cp, cnd = cnd_pair
    n = args.check_size
    result = {"check_size": n}
    ndimage = import_scipy_ndimage()
    if ndimage is None:
        why = "skipped: SciPy is not installed (apt-get install python3-scipy)"
        result.update(cupy_edt_vs_scipy=why, cupy_edt_vs_scipy_max_abs_diff=None,
                      chebyshev_vs_scipy=why, manhattan_vs_scipy=why,
                      cupy_edt_vs_scipy_ok=None, chebyshev_vs_scipy_ok=None,
                      manhattan_vs_scipy_ok=None, scipy=None)
        return result
    import scipy
    result["scipy"] = scipy.__version__
    world = make_world(n, args.seed)
    mask = world == 0
    ref = ndimage.distance_transform_edt(mask)
    got = cp.asnumpy(cnd.distance_transform_edt(cp.asarray(mask)))
    diff = float(np.max(np.abs(got.astype(np.float64) - ref))) if ref.size else 0.0
    result.update(cupy_edt_vs_scipy="equal" if diff <= 1e-6 else "DIFFERENT",
                  cupy_edt_vs_scipy_ok=diff <= 1e-6, cupy_edt_vs_scipy_max_abs_diff=diff)
    world_path = os.path.join(tmp, f"check-world-{n}.npy")
    np.save(world_path, world)
    for metric, scipy_metric in (("chebyshev", "chessboard"), ("manhattan", "taxicab")):
        if metric not in args.case_list:
            result[f"{metric}_vs_scipy"], result[f"{metric}_vs_scipy_ok"] = "not run", None
            continue
        field_path = os.path.join(tmp, f"check-{metric}.npy")
        doc, _ = run_voxfield(args.voxfield, world_path, field_path,
                              os.path.join(tmp, "check.json"), args.device,
                              ["--metric", metric, "--format", "u32"], 0, 1)
        ours = np.load(field_path)
        theirs = ndimage.distance_transform_cdt(mask, metric=scipy_metric)
        same = ours.shape == theirs.shape and bool(np.array_equal(ours.astype(np.int64), theirs))
        if same:
            text = f"equal to SciPy cdt(metric='{scipy_metric}') on {n}^3"
        elif ours.shape != theirs.shape:
            text = f"DIFFERENT from SciPy cdt on {n}^3: shape {ours.shape}, expected {theirs.shape}"
        else:
            bad = ours.astype(np.int64) != theirs
            z, y, x = (int(v) for v in np.argwhere(bad)[0])
            text = (f"DIFFERENT from SciPy cdt(metric='{scipy_metric}') on {n}^3 at "
                    f"{int(bad.sum())} voxels; first (z,y,x)=({z},{y},{x}): ours {ours[z, y, x]}, "
                    f"SciPy {theirs[z, y, x]}")
        result[f"{metric}_vs_scipy"], result[f"{metric}_vs_scipy_ok"] = text, same
        os.remove(field_path)
    os.remove(world_path)
    return result


# ---------------------------------------------------------------------------- one size


def case_flags(name, shape):
    l1_fmt = "u16" if sum(shape) - 3 <= 0xFFFF else "u32"
    linf_fmt = "u16" if max(shape) - 1 <= 0xFFFF else "u32"
    return {
        "manhattan": ["--metric", "manhattan", "--format", l1_fmt],
        "euclidean": ["--metric", "euclidean", "--format", "f32"],
        "chebyshev": ["--metric", "chebyshev", "--format", linf_fmt],
        "signed-euclidean": ["--signed", "--metric", "euclidean", "--format", "f32"],
        "euclidean-indices": ["--metric", "euclidean", "--format", "f32"],
        "euclidean-sampling": ["--metric", "euclidean", "--format", "f64", "--spacing",
                               ",".join(str(v) for v in SAMPLING_XYZ)],
    }[name]


PEER_CALLS = {
    "manhattan": "distance_transform_edt(mask) (Euclidean: another metric, timing only)",
    "euclidean": "distance_transform_edt(mask)",
    "chebyshev": None,
    "signed-euclidean": "edt(~solid) - edt(solid) on the world padded by one empty voxel, cropped",
    "euclidean-indices": "distance_transform_edt(mask, return_distances=True, return_indices=True)",
    "euclidean-sampling": "distance_transform_edt(mask, sampling=" + str(SAMPLING_XYZ[::-1]) + ")",
}


def run_size(args, cp, cnd, n, f32_ok, small, tmp, world_name="floor-spheres"):
    """Every case at N^3 on the named world of bench/worlds.py: a list of row dicts."""
    progress(f"N={n}: building the world {world_name}")
    world = make_named(world_name, n, args.seed)
    shape = world.shape
    solid = int(np.count_nonzero(world))
    world_path = os.path.join(tmp, f"world-{n}.npy")
    np.save(world_path, world)
    mask_gpu = cp.asarray(world == 0)
    del world
    pool = cp.get_default_memory_pool()

    def edt(m, f64=True, **kw):
        if f64:
            return cnd.distance_transform_edt(m, **kw)
        return cnd.distance_transform_edt(m, float64_distances=False, **kw)

    padded = None

    def signed_peer(f64):
        d = edt(padded[1], f64)   # empty voxels: distance to the nearest solid
        d -= edt(padded[0], f64)  # solid voxels: minus the distance to the nearest empty one
        return d[1:-1, 1:-1, 1:-1]

    peer_fns = {
        "edt": lambda f64: edt(mask_gpu, f64),
        "signed": signed_peer,
        "indices": lambda f64: edt(mask_gpu, f64, return_distances=True, return_indices=True),
        "sampling": lambda f64: edt(mask_gpu, f64, sampling=SAMPLING_XYZ[::-1]),
    }
    peer_of = {"manhattan": "edt", "euclidean": "edt", "signed-euclidean": "signed",
               "euclidean-indices": "indices", "euclidean-sampling": "sampling"}
    peer_times = {}

    def peer_timing(kind):
        if kind not in peer_times:
            progress(f"N={n}: timing CuPy ({kind})")
            f64 = time_cupy(cp, lambda: peer_fns[kind](True), args.warmup, args.repeat)
            f32 = (time_cupy(cp, lambda: peer_fns[kind](False), args.warmup, args.repeat)
                   if f32_ok else None)
            peer_times[kind] = (f64, f32)
            pool.free_all_blocks()
        return peer_times[kind]

    progress(f"N={n}: CuPy float64 EDT (the reference of the checks)")
    try:
        ref_edt = edt(mask_gpu)
    except cp.cuda.memory.OutOfMemoryError as e:
        # CuPy's PBA+ pads the array to a cube of its longest side: long worlds do not fit.
        print(f"{world_name:<13} skipped: CuPy's distance_transform_edt cannot run on {shape} "
              f"({e}); nothing to check voxfield against on this world", flush=True)
        del mask_gpu
        pool.free_all_blocks()
        os.remove(world_path)
        args.skipped.append({"world": world_name, "n": n, "shape": list(shape),
                             "why": f"CuPy distance_transform_edt: {e}"})
        return []
    rows = []
    for name in args.case_list:
        flags = case_flags(name, shape)
        field_path = os.path.join(tmp, f"{name}-{n}.npy")
        idx_path = os.path.join(tmp, f"{name}-{n}-indices.npy")
        json_path = os.path.join(tmp, f"{name}-{n}.json")
        run_flags = flags + (["--indices", idx_path] if name == "euclidean-indices" else [])
        if name == "signed-euclidean":
            sp = cp.zeros(tuple(s + 2 for s in shape), dtype=cp.bool_)
            sp[1:-1, 1:-1, 1:-1] = ~mask_gpu
            padded = (sp, ~sp)
        pool.free_all_blocks()  # leave the GPU's memory to voxfield's OpenCL context
        progress(f"N={n}: voxfield {name} ({args.warmup} warm-up, {args.repeat} timed)")
        doc, cmd = run_voxfield(args.voxfield, world_path, field_path, json_path, args.device,
                                run_flags, args.warmup, args.repeat)
        kernel_ms = [float(v) for v in doc["kernel_ms_samples"]]
        ours = np.load(field_path, mmap_mode="r")

        progress(f"N={n}: checking {name}")
        bounds_ok = None
        if solid == 0:
            ok, detail = None, "skipped (no solid voxel)"
        elif name == "manhattan":
            ok, detail = check_bounds(cp, ours, ref_edt, "manhattan")
            bounds_ok = ok
            if small.get("manhattan_vs_scipy_ok") is not None:
                ok = ok and small["manhattan_vs_scipy_ok"]
                detail += f"; {small['manhattan_vs_scipy']}"
        elif name == "chebyshev":
            ok, detail = check_bounds(cp, ours, ref_edt, "chebyshev")
            bounds_ok = ok
            s_ok = small.get("chebyshev_vs_scipy_ok")
            if s_ok is None:
                detail += ("; not compared for equality with a peer (CuPy has no chessboard "
                           f"transform; SciPy: {small.get('chebyshev_vs_scipy')})")
            else:
                ok = ok and s_ok
                detail += f"; {small['chebyshev_vs_scipy']}"
        elif name == "euclidean":
            ok, detail = check_close(cp, ours, ref_edt)
        elif name == "signed-euclidean":
            ref = signed_peer(True)
            ok, detail = check_close(cp, ours, ref, "CuPy padded signed")
            del ref
        elif name == "euclidean-sampling":
            ref = peer_fns["sampling"](True)
            ok, detail = check_close(cp, ours, ref, "CuPy sampled")
            del ref
        else:  # euclidean-indices
            ok, detail = check_close(cp, ours, ref_edt)
            idx = np.load(idx_path, mmap_mode="r")
            ok2, detail2 = check_indices(cp, ours, idx, mask_gpu)
            ok, detail = ok and ok2, f"{detail}; {detail2}"
            del idx
        del ours
        pool.free_all_blocks()
        for path in (field_path, idx_path, json_path):
            if os.path.exists(path):
                os.remove(path)

        peer = peer_of.get(name)
        f64_ms, f32_ms = peer_timing(peer) if peer else (None, None)
        if name == "signed-euclidean":
            padded = None
            pool.free_all_blocks()
        kmed = statistics.median(kernel_ms)
        row = {
            "case": name,
            "size": [int(shape[2]), int(shape[1]), int(shape[0])],
            "n": n,
            "world": world_name,
            "voxels": int(np.prod(shape)),
            "solid": solid,
            "voxfield_flags": flags + (["--indices"] if name == "euclidean-indices" else []),
            "voxfield_command": cmd,
            "format": doc.get("format"),
            "variant": doc.get("variant"),
            "kernel_ms": spread(kernel_ms),
            "kernel_ms_median": kmed,
            "end_to_end_ms": float(doc["end_to_end_ms"]) if "end_to_end_ms" in doc else None,
            "upload_ms": doc.get("upload_ms"),
            "download_ms": doc.get("download_ms"),
            "cupy_call": PEER_CALLS[name],
            "cupy_comparable": name not in ("manhattan", "chebyshev"),
            "cupy_f64_ms": spread(f64_ms),
            "cupy_f32_ms": spread(f32_ms),
            "ratio_cupy_f64_over_kernel": statistics.median(f64_ms) / kmed
            if f64_ms and kmed > 0 else None,
            "ratio_cupy_f32_over_kernel": statistics.median(f32_ms) / kmed
            if f32_ms and kmed > 0 else None,
            "check_ok": ok,
            "check": detail,
            "bounds_vs_edt_ok": bounds_ok,
            "voxfield_device": doc.get("device"),
            "voxfield_commit": doc.get("commit"),
        }
        rows.append(row)
        print_row(row)
    del ref_edt, mask_gpu
    pool.free_all_blocks()
    os.remove(world_path)
    return rows


# ---------------------------------------------------------------------------- output


HEADER = (f"{'world':<13} {'case':<18} {'N':>5} {'format':>6} {'voxfield ms':>11} {'e2e ms':>9}"
          f" {'CuPy f64 ms':>11} {'CuPy f32 ms':>11} {'f64/ours':>8} {'f32/ours':>8}  check")


def fmt(value, spec):
    """value formatted by spec (">9.1f"), or a "-" as wide."""
    if value is not None:
        return format(value, spec)
    return format("-", spec.split(".")[0].rstrip("fd"))


def print_row(r):
    f64 = r["cupy_f64_ms"]["median"] if r["cupy_f64_ms"] else None
    f32 = r["cupy_f32_ms"]["median"] if r["cupy_f32_ms"] else None
    status = "ok" if r["check_ok"] else ("skipped" if r["check_ok"] is None else "FAILED")
    print(f"{r['world']:<13} {r['case']:<18} {r['n']:>5} {r['format'] or '-':>6} {r['kernel_ms_median']:>11.3f}"
          f" {fmt(r['end_to_end_ms'], '>9.1f')} {fmt(f64, '>11.3f')} {fmt(f32, '>11.3f')}"
          f" {fmt(r['ratio_cupy_f64_over_kernel'], '>8.2f')}"
          f" {fmt(r['ratio_cupy_f32_over_kernel'], '>8.2f')}  {status}: {r['check']}", flush=True)


def legacy_summary(rows, small):
    """The fields bench/summarize.py tabulates (its CuPy table), from one size's manhattan row."""
    taxicab = next((r for r in rows if r["case"] == "manhattan"), None)
    if taxicab is None or not taxicab["cupy_f64_ms"]:
        return {}
    f64, f32 = taxicab["cupy_f64_ms"], taxicab["cupy_f32_ms"]
    return {
        "size": taxicab["size"],
        "ours_metric": "manhattan",
        "ours_kernel_ms_median": taxicab["kernel_ms_median"],
        "ours_kernel_ms": taxicab["kernel_ms"]["samples"],
        "ours_end_to_end_ms": taxicab["end_to_end_ms"],
        "cupy_metric": "euclidean (different from ours: not compared for equality)",
        "cupy_edt_ms_median": f64["median"],
        "cupy_edt_ms": f64["samples"],
        "cupy_edt_f32_ms_median": f32["median"] if f32 else None,
        "cupy_edt_f32_ms": f32["samples"] if f32 else None,
        "ratio_cupy_over_ours_kernel": taxicab["ratio_cupy_f64_over_kernel"],
        "bounds_l1_vs_edt_hold": taxicab["bounds_vs_edt_ok"],
        "cupy_vs_scipy_edt": small.get("cupy_edt_vs_scipy"),
        "cupy_vs_scipy_edt_max_abs_diff": small.get("cupy_edt_vs_scipy_max_abs_diff"),
        "cupy_vs_scipy_check_size": small.get("check_size"),
    }


def write_json(path, common, rows, small):
    sizes = sorted({r["n"] for r in rows})
    record = dict(common)
    record.update({
        "sizes": sizes,
        "small_checks": small,
        "all_checks_pass": not any_failed(rows, small),
        "rows": rows,
    })
    if len(sizes) == 1 and len({r["world"] for r in rows}) == 1:
        record.update(legacy_summary(rows, small))
    tmp_path = path + ".partial"
    with open(tmp_path, "w") as f:
        json.dump(record, f, indent=2)
        f.write("\n")
    os.replace(tmp_path, path)


def any_failed(rows, small):
    return (any(r["check_ok"] is False for r in rows) or
            small.get("cupy_edt_vs_scipy_ok") is False)


def write_all(args, common, rows, small):
    if not args.json:
        return
    if "{size}" in args.json:
        for n in sorted({r["n"] for r in rows}):
            write_json(args.json.replace("{size}", str(n)), common,
                       [r for r in rows if r["n"] == n], small)
    else:
        write_json(args.json, common, rows, small)


# ---------------------------------------------------------------------------- main


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog="\n\n".join(__doc__.split("\n\n")[1:]))
    ap.add_argument("--size", type=int, help="one world edge N (N^3; default 256 without --sizes)")
    ap.add_argument("--sizes", type=int, nargs="+", metavar="N",
                    help="world edges to run in turn, e.g. --sizes 512 1024")
    ap.add_argument("--seed", type=int, default=6683787, help="world seed")
    ap.add_argument("--voxfield", default=os.path.join(REPO, "build", "viewer", "voxfield"),
                    help="voxfield binary (default: build/viewer/voxfield)")
    ap.add_argument("--device", default="gpu", help="voxfield --device (default: gpu)")
    ap.add_argument("--repeat", type=int, default=20, help="timed runs of each (default 20)")
    ap.add_argument("--warmup", type=int, default=3, help="untimed runs first (default 3)")
    ap.add_argument("--cases", default=",".join(CASES),
                    help=f"comma-separated subset of {','.join(CASES)} (default: all)")
    ap.add_argument("--check-size", type=int, default=64,
                    help="edge of the small world checked against SciPy (default 64)")
    ap.add_argument("--tmpdir", help="folder for the world and the fields (default: the system's; "
                    "1024^3 needs about 18 GB free at the peak, the indices case)")
    ap.add_argument("--worlds", default="floor-spheres",
                    help=f"comma-separated worlds of bench/worlds.py ({','.join(WORLDS).replace('%', '%%')}) or 'all', "
                    "each run at every size (default: floor-spheres)")
    ap.add_argument("--json", help="write the comparison to this JSON file; '{size}' in the name "
                    "writes one file per size")
    args = ap.parse_args()

    if args.size is not None and args.sizes:
        ap.error("give --size N or --sizes N [N ...], not both")
    sizes = args.sizes or [args.size if args.size is not None else 256]
    if len(set(sizes)) != len(sizes):
        ap.error(f"--sizes: repeated size in {sizes}")
    if args.repeat < 1 or min(sizes) < 1 or args.check_size < 1 or args.warmup < 0:
        ap.error("sizes, --repeat and --check-size must be at least 1, --warmup at least 0")
    args.skipped = []  # worlds the peer could not run on
    args.world_list = WORLDS if args.worlds == "all" else [w for w in args.worlds.split(",") if w]
    bad_worlds = [w for w in args.world_list if w not in WORLDS]
    if bad_worlds or not args.world_list:
        ap.error(f"--worlds: unknown {','.join(bad_worlds) or '(none given)'}; expected "
                 f"{','.join(WORLDS)} or all")
    args.case_list = [c for c in args.cases.split(",") if c]
    unknown = [c for c in args.case_list if c not in CASES]
    if unknown or not args.case_list:
        ap.error(f"--cases: unknown {','.join(unknown) or '(none given)'}; expected {','.join(CASES)}")
    if not (os.path.isfile(args.voxfield) and os.access(args.voxfield, os.X_OK)):
        ap.error(f"voxfield binary not found: {args.voxfield} (build it first, or pass --voxfield)")
    if args.json and os.path.dirname(args.json) and not os.path.isdir(os.path.dirname(args.json)):
        ap.error(f"--json {args.json}: folder does not exist")
    if args.tmpdir and not os.path.isdir(args.tmpdir):
        ap.error(f"--tmpdir {args.tmpdir}: folder does not exist")
    cp, cnd = import_cupy()

    # float32 output (float64_distances=False) is in newer CuPy only: probe on a tiny array.
    probe = cp.ones((4, 4, 4), dtype=cp.bool_)
    probe[0, 0, 0] = False
    try:
        cnd.distance_transform_edt(probe, float64_distances=False)
        f32_ok = True
    except TypeError:
        f32_ok = False
    del probe

    version_text, commit = voxfield_version(args.voxfield)
    props = cp.cuda.runtime.getDeviceProperties(cp.cuda.Device().id)
    gpu_name = props["name"].decode() if isinstance(props["name"], bytes) else str(props["name"])
    try:
        cuda_runtime = cp.cuda.runtime.runtimeGetVersion()
    except Exception:  # noqa: BLE001 (informative only)
        cuda_runtime = None
    smi = nvidia_smi()
    common = {
        "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
        # The voxfield binary's own commit (the checkout on the GPU machine may differ).
        "commit": commit or git_commit(),
        "voxfield_version": version_text,
        "checkout_commit": git_commit(),
        "device_arg": args.device,
        "cupy_device": gpu_name,
        "nvidia_smi": smi,
        "voxfield_devices": voxfield_devices(args.voxfield),
        "world": f"{','.join(args.world_list)} seed={args.seed} (bench/worlds.py)",
        "worlds": args.world_list,
        "skipped_worlds": args.skipped,
        "seed": args.seed,
        "repeat": args.repeat,
        "warmup": args.warmup,
        "cases": args.case_list,
        "tolerance": "float32 fields: |ours - CuPy float64| <= 2^-23 |CuPy float64| per voxel",
        "cupy_f32_supported": f32_ok,
        "cupy": cp.__version__,
        "cuda_driver": cp.cuda.runtime.driverGetVersion(),
        "cuda_runtime": cuda_runtime,
        "numpy": np.__version__,
    }
    print(f"voxfield {commit or '?'} on --device {args.device}; CuPy {cp.__version__} on "
          f"{gpu_name}; sizes {', '.join(map(str, sizes))}; medians of {args.repeat} after "
          f"{args.warmup} warm-up", flush=True)

    rows = []
    with tempfile.TemporaryDirectory(prefix="voxfield_cupy_", dir=args.tmpdir) as tmp:
        progress(f"checks on {args.check_size}^3 against SciPy")
        small = small_checks(args, (cp, cnd), tmp)
        print(f"check: CuPy EDT vs SciPy EDT on {args.check_size}^3: "
              f"{small['cupy_edt_vs_scipy']}" +
              (f" (max |diff| {small['cupy_edt_vs_scipy_max_abs_diff']:.2e})"
               if small.get("cupy_edt_vs_scipy_max_abs_diff") is not None else ""), flush=True)
        print(HEADER, flush=True)
        for n in sizes:
            for world_name in args.world_list:
                rows.extend(run_size(args, cp, cnd, n, f32_ok, small, tmp, world_name))
                device = rows[-1]["voxfield_device"] or {}
                common["device"] = device.get("name")  # the string bench/summarize.py prints
                common["driver"] = device.get("driver")
                # After every world: a later failure or time limit keeps these.
                write_all(args, common, rows, small)

    device_name = common.get("device")
    print(f"voxfield on: {device_name}; CuPy on: {gpu_name}"
          + (f"; nvidia-smi: {', '.join(g.get('name', '?') + ' driver ' + g.get('driver_version', '?') for g in smi)}"
             if isinstance(smi, list) and smi else ""))
    print("voxfield ms = median kernel time (OpenCL profiling); e2e = the run's end-to-end time from "
          "its JSON (first run: includes the kernel build); CuPy ms = median of CUDA-event timings "
          "(float64 output, and float32 via float64_distances=False); f64/ours = CuPy / voxfield.")
    for name in args.case_list:
        if PEER_CALLS[name]:
            print(f"  {name}: CuPy {PEER_CALLS[name]}")
        else:
            print(f"  {name}: no CuPy peer (no chessboard transform in CuPy)")
    if args.json:
        names = ([args.json.replace("{size}", str(n)) for n in sizes] if "{size}" in args.json
                 else [args.json])
        print(f"wrote {', '.join(names)}")
    return 1 if any_failed(rows, small) else 0


if __name__ == "__main__":
    sys.exit(main())
