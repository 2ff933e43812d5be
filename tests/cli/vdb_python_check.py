"""`voxfield generate -o F.vdb` read by OpenVDB's Python module (Debian's python3-openvdb).

Run by CTest: python3 vdb_python_check.py VOXFIELD_EXE DATA_DIR. Writes the same field as .npy
and .vdb and checks, voxel by voxel with numpy, that the 'distance' grid holds the field where
it is below the bound (active) and the bound elsewhere (inactive), with the grid class, voxel
size and background the command line asked for; then the bad inputs and outputs (exit 2, one
line, no file).
"""
import json
import os
import subprocess
import sys
import tempfile

import numpy as np
import pyopenvdb as vdb

EXE, DATA = sys.argv[1], sys.argv[2]
MODEL = os.path.join(DATA, "vox", "veh_car1.vox")


def run(*args):
    return subprocess.run([EXE, *args], capture_output=True, text=True)


def check_field(tmp, extra, bound, level_set, voxel_size):
    npy, out = os.path.join(tmp, "f.npy"), os.path.join(tmp, "f.vdb")
    for target in (npy, out):
        r = run("generate", MODEL, "-o", target, "--device", "cpu", *extra)
        assert r.returncode == 0, r.stderr
    field = np.load(npy).astype(np.float64)  # (Z, Y, X)
    # Debian's module has no Int32Grid type (so no readAll on this file): grids by name.
    grid = vdb.read(out, "distance")
    assert vdb.readGridMetadata(out, "distance").name == "distance"
    assert grid.gridClass == (vdb.GridClass.LEVEL_SET if level_set else vdb.GridClass.UNKNOWN)
    assert grid.background == np.float32(bound), grid.background
    assert np.allclose(grid.transform.voxelSize(), voxel_size)
    dense = np.empty(field.shape[::-1], dtype=np.float32)  # (X, Y, Z): index (i, j, k)
    grid.copyToArray(dense, ijk=(0, 0, 0))
    dense = dense.transpose(2, 1, 0)
    active = np.abs(field) < bound
    want = np.where(active, field, np.where(field < 0, -bound, bound)).astype(np.float32)
    wrong = int(np.count_nonzero(dense != want))
    assert wrong == 0, f"{wrong} voxels differ"
    on = sum(item.count for item in grid.citerOnValues())
    assert on == int(np.count_nonzero(active)), (on, int(np.count_nonzero(active)))
    return int(np.count_nonzero(active))


with tempfile.TemporaryDirectory() as tmp:
    n = check_field(tmp, ["--max-distance", "6"], 6.0, False, 1.0)
    print(f"manhattan u16, D 6: {n} active voxels equal")
    n = check_field(tmp, ["--metric", "euclidean", "--signed", "--max-distance", "2.5",
                          "--spacing", "0.5,0.5,0.5"], 2.5, True, 0.5)
    print(f"euclidean signed f32, spacing 0.5, D 2.5: {n} active voxels equal")
    n = check_field(tmp, ["--metric", "chebyshev"], 16.0, False, 1.0)
    print(f"chebyshev, default bound 16: {n} active voxels equal")
    n = check_field(tmp, ["--sparse", "--max-distance", "6"], 6.0, False, 1.0)
    print(f"--sparse, D 6: {n} active voxels equal")

    # The file read back as input: its first grid is the material, i.e. the world's solids.
    info = json.loads(run("info", os.path.join(tmp, "f.vdb"), "--json").stdout)
    assert info["kind"] == "vdb" and info["grid"] == "material", info
    solid = int(np.count_nonzero(np.load(os.path.join(tmp, "f.npy")) == 0))
    assert info["solid_voxels"] == solid, (info["solid_voxels"], solid)
    print(f"info on the .vdb: grid 'material', {solid} solid voxels")

    # A grid too wide for a dense world (extent about 1e6 x 6 x 9e5 voxels): generated sparse
    # without --sparse, read and written tile by tile; around each of its two solid voxels the
    # field is the Manhattan distance below the bound, and nothing else is active.
    wide_in, wide_out = os.path.join(tmp, "wide_in.vdb"), os.path.join(tmp, "wide_out.vdb")
    fog = vdb.FloatGrid()
    fog.name = "fog"
    solids = [(0, 0, 0), (1000000, 5, 900000)]
    acc = fog.getAccessor()
    for ijk in solids:
        acc.setValueOn(ijk, 1.0)
    vdb.write(wide_in, grids=[fog])
    r = run("generate", wide_in, "-o", wide_out, "--device", "cpu", "--max-distance", "4")
    assert r.returncode == 0, r.stderr
    grid = vdb.read(wide_out, "distance")
    racc = grid.getConstAccessor()
    want_on = 0
    for sx, sy, sz in solids:
        for dz in range(-4, 5):
            for dy in range(-4, 5):
                for dx in range(-4, 5):
                    x, y, z = sx + dx, sy + dy, sz + dz
                    if not (0 <= x <= 1000000 and 0 <= y <= 5 and 0 <= z <= 900000):
                        continue
                    d = abs(dx) + abs(dy) + abs(dz)
                    value, on = racc.probeValue((x, y, z))
                    assert on == (d < 4), ((x, y, z), d, value, on)
                    assert value == (d if d < 4 else 4), ((x, y, z), d, value)
                    want_on += d < 4
    on = sum(item.count for item in grid.citerOnValues())
    assert on == want_on, (on, want_on)
    print(f"wide .vdb input (1e6 x 6 x 9e5, auto sparse): {on} active voxels, all exact")

    # Refused before any output: non-uniform spacing, unreadable .vdb input, missing grid.
    bad = os.path.join(tmp, "bad.vdb")
    with open(bad, "w") as f:
        f.write("not a vdb\n")
    out = os.path.join(tmp, "o.vdb")
    for args in (["generate", MODEL, "-o", out, "--metric", "euclidean", "--spacing", "1,2,1"],
                 ["generate", bad, "-o", out],
                 ["generate", os.path.join(tmp, "f.vdb"), "--grid", "nope", "-o", out],
                 ["generate", os.path.join(tmp, "f.vdb"), "--grid", "nope", "--sparse", "-o", out],
                 ["info", bad]):
        r = run(*args)
        assert r.returncode == 2, (args, r.returncode, r.stderr)
        assert len(r.stderr.strip().splitlines()) == 1, r.stderr
        assert not os.path.exists(out), args
    print("bad input: exit 2, one line, no output")
print("ok")
