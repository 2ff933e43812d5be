"""voxfield.Field as a front end over the library's scene: undo / redo of edit calls and the
falling-sand steps, against CPU references on PoCL (VOXFIELD_DEVICE=cpu).

References: the world after undo / redo is the world the edits started from (or reached),
checked voxel for voxel; the sand steps against `sand_step` below, a Python transcription of
core's CPU reference (core/src/sand.cpp, rules in core/include/voxfield/core/sand.hpp); every
field against scipy.ndimage (manhattan: distance_transform_cdt taxicab) and against the
module's one-shot voxfield.distance_transform of the Field's world.
"""

import numpy as np
import pytest
from scipy import ndimage

import voxfield

MASK = (1 << 64) - 1
AIR, OUTSIDE = 0, 256


def sand_hash(x):
    """splitmix64's output function, as core's sand_hash."""
    z = (x + 0x9E3779B97F4A7C15) & MASK
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & MASK
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & MASK
    return z ^ (z >> 31)


def sand_step(world, seed, step, sand=2, water=3):
    """One step of core's falling-sand automaton on a (Z, Y, X) uint8 world; returns the new
    world (core/src/sand.cpp, line for line)."""
    nz, ny, nx = world.shape
    ox, oy, oz = (step >> 1) & 1, step & 1, (step >> 2) & 1
    nbx, nby, nbz = (nx + ox + 1) // 2, (ny + oy + 1) // 2, (nz + oz + 1) // 2
    key = sand_hash(sand_hash(seed) ^ step)
    before = world
    out = world.copy()

    def at(x, y, z):
        if 0 <= x < nx and 0 <= y < ny and 0 <= z < nz:
            return int(before[z, y, x])
        return OUTSIDE

    for k in range(nbz):
        for j in range(nby):
            for i in range(nbx):
                x0, y0, z0 = 2 * i - ox, 2 * j - oy, 2 * k - oz
                cell = [[at(x0 + (c & 1), y0 + layer, z0 + (c >> 1)) for c in range(4)]
                        for layer in range(2)]
                if not any(v in (sand, water) for row in cell for v in row):
                    continue
                h = sand_hash(key ^ ((k * nby + j) * nbx + i))
                r = h & 3
                moved = [[False] * 4, [False] * 4]
                for n in range(4):  # 1. falling, top layer
                    c = (n + r) & 3
                    v = cell[1][c]
                    if v not in (sand, water):
                        continue
                    below = cell[0][c]
                    if below == AIR or (v == sand and below == water and not moved[0][c]):
                        cell[0][c], cell[1][c] = v, below
                        moved[0][c] = True
                        moved[1][c] = below != AIR
                        continue
                    a, b = c ^ 1, c ^ 2
                    free_a, free_b = cell[0][a] == AIR, cell[0][b] == AIR
                    if not free_a and not free_b:
                        continue
                    if free_a and free_b:
                        t = b if (h >> (8 + c)) & 1 else a
                    else:
                        t = a if free_a else b
                    cell[0][t] = v
                    cell[1][c] = AIR
                    moved[0][t] = True
                for layer in (1, 0):  # 2. sideways water, top layer first
                    for n in range(4):
                        c = (n + r) & 3
                        if cell[layer][c] != water or moved[layer][c]:
                            continue
                        if layer == 0 and at(x0 + (c & 1), y0 - 1, z0 + (c >> 1)) == AIR:
                            continue
                        a, b = c ^ 1, c ^ 2
                        free_a, free_b = cell[layer][a] == AIR, cell[layer][b] == AIR
                        if not free_a and not free_b:
                            continue
                        if free_a and free_b:
                            t = b if (h >> (16 + c + 4 * layer)) & 1 else a
                        else:
                            t = a if free_a else b
                        cell[layer][t] = water
                        cell[layer][c] = AIR
                        moved[layer][t] = True
                for layer in range(2):
                    for c in range(4):
                        x, y, z = x0 + (c & 1), y0 + layer, z0 + (c >> 1)
                        if 0 <= x < nx and 0 <= y < ny and 0 <= z < nz:
                            out[z, y, x] = cell[layer][c]
    return out


def sand_world(shape, seed, sand=2, water=3):
    """A floor (1) at y = 0, a walled basin (4) of water, a sand heap and loose grains of sand
    and water in the air: every rule of the automaton has work."""
    nz, ny, nx = shape
    rng = np.random.default_rng(seed)
    w = np.zeros(shape, np.uint8)
    w[:, 0, :] = 1
    w[1:nz - 1, 1:4, nx // 2:nx - 1] = 4
    w[2:nz - 2, 1:4, nx // 2 + 1:nx - 2] = water
    w[nz // 3:nz // 3 + 3, 1:ny // 2, 1:4] = sand
    air = (w == 0) & (rng.random(shape) < 0.08)
    w[air] = np.where(rng.random(shape) < 0.5, sand, water)[air]
    return w


def l1_reference(world):
    return ndimage.distance_transform_cdt(world == 0, metric="taxicab")


def test_sand_reference_moves_something_and_keeps_counts():
    w = sand_world((9, 10, 11), 5)
    after = sand_step(w, 7, 0)
    assert not np.array_equal(after, w)
    assert np.array_equal(np.bincount(after.ravel(), minlength=256),
                          np.bincount(w.ravel(), minlength=256))


def test_step_sand_equals_the_cpu_reference_step_by_step():
    w = sand_world((11, 12, 13), 1)
    field = voxfield.Field(w)
    assert field.sand_steps == 0
    want = w
    step = 0
    total_changed = 0
    for n in (1, 1, 2, 5, 3):  # steps numbered on across calls
        stats = field.step_sand(n, seed=9)
        for _ in range(n):
            nxt = sand_step(want, 9, step)
            total_changed += int((nxt != want).sum())
            want, step = nxt, step + 1
        assert stats["steps"] == n and field.sand_steps == step
        got = field.world()
        np.testing.assert_array_equal(got, want, err_msg=f"after step {step}")
        np.testing.assert_array_equal(field.distances(), l1_reference(got))
    assert total_changed > 0


@pytest.mark.parametrize("kwargs", [dict(metric="euclidean"), dict(metric="chebyshev"),
                                    dict(signed=True), dict(max_distance=3),
                                    dict(format="packed32"),
                                    dict(metric="euclidean", sampling=(1.0, 2.0, 0.5))])
def test_step_sand_keeps_every_field_exact(kwargs):
    w = sand_world((10, 9, 12), 2, sand=5, water=6)
    field = voxfield.Field(w, **kwargs)
    want = w
    for step in range(4):
        want = sand_step(want, 123, step, sand=5, water=6)
    stats = field.step_sand(4, seed=123, sand=5, water=6)
    assert stats["voxels_changed"] > 0
    got = field.world()
    np.testing.assert_array_equal(got, want)
    field_now = field.distances()
    one_shot = voxfield.distance_transform(got, **kwargs)
    assert field_now.dtype == one_shot.dtype
    np.testing.assert_array_equal(field_now, one_shot)


def test_step_sand_zero_steps_and_a_static_world_change_nothing():
    w = np.zeros((6, 7, 8), np.uint8)
    w[:, 0, :] = 1
    w[2, 1, 3] = 9
    field = voxfield.Field(w)
    assert field.step_sand(0)["voxels_changed"] == 0 and field.sand_steps == 0
    stats = field.step_sand(3)
    assert stats["voxels_changed"] == 0 and field.sand_steps == 3
    np.testing.assert_array_equal(field.world(), w)
    np.testing.assert_array_equal(field.distances(), l1_reference(w))


def test_undo_and_redo_restore_worlds_and_fields():
    rng = np.random.default_rng(4)
    w = np.where(rng.random((12, 14, 16)) < 0.01, 7, 0).astype(np.uint8)
    field = voxfield.Field(w, metric="euclidean")
    assert not field.can_undo and not field.can_redo
    nothing = field.undo()
    assert nothing["edits"] == 0 and nothing["voxels_changed"] == 0
    assert field.redo()["edits"] == 0
    worlds = [w]
    for op, shape, center, radius, material in (("place", "sphere", (5, 6, 7), 3, 2),
                                                ("paint", "cube", (5, 6, 7), 2, 9),
                                                ("erase", "sphere", (6, 6, 7), 2, 1)):
        stats = field.edit(op, shape, center, radius, material)
        assert stats["voxels_changed"] > 0
        worlds.append(field.world())
    # The batch of an edit file is one undo step.
    field.apply_edits("place cube 2 2 2 1 3\nplace sphere 12 10 8 2 4\n")
    worlds.append(field.world())
    assert field.can_undo and not field.can_redo
    for want in reversed(worlds[:-1]):
        stats = field.undo()
        assert stats["edits"] == 1 and stats["voxels_changed"] > 0
        got = field.world()
        np.testing.assert_array_equal(got, want)
        np.testing.assert_array_equal(field.distances(),
                                      voxfield.distance_transform(got, metric="euclidean"))
    assert not field.can_undo and field.can_redo
    assert field.undo()["edits"] == 0
    for want in worlds[1:3]:
        field.redo()
        got = field.world()
        np.testing.assert_array_equal(got, want)
        np.testing.assert_array_equal(field.distances(),
                                      voxfield.distance_transform(got, metric="euclidean"))
    # A new edit clears what could be redone.
    assert field.can_redo
    field.edit("place", "cube", (0, 0, 0), 0, 5)
    assert not field.can_redo and field.redo()["edits"] == 0
    field.undo()
    np.testing.assert_array_equal(field.world(), worlds[2])


def test_an_edit_that_changes_nothing_is_not_an_undo_step():
    w = np.zeros((5, 6, 7), np.uint8)
    field = voxfield.Field(w)
    assert field.edit("erase", "sphere", (2, 2, 2), 2)["voxels_changed"] == 0
    assert not field.can_undo


def test_undo_after_sand_steps():
    # An edit that sand never reaches (wall material, above everything that moves) undoes
    # after the steps.
    clear = sand_world((10, 12, 14), 3)
    clear[:, 8:, :] = 0
    field = voxfield.Field(clear)
    field.edit("place", "cube", (6, 10, 5), 1, 4)
    placed = field.world()
    field.step_sand(6, seed=2)
    want = placed
    for step in range(6):
        want = sand_step(want, 2, step)
    field.undo()
    want = np.where((placed == 4) & (clear != 4), 0, want).astype(np.uint8)
    got = field.world()
    np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(field.distances(), l1_reference(got))
    # An edit of sand that then falls cannot be undone: ValueError, nothing changes, and the
    # history is cleared.
    field.edit("place", "cube", (3, 10, 4), 1, 2)
    field.step_sand(2)
    before = field.world()
    with pytest.raises(ValueError):
        field.undo()
    assert not field.can_undo and not field.can_redo
    np.testing.assert_array_equal(field.world(), before)
    np.testing.assert_array_equal(field.distances(), l1_reference(before))


def test_step_sand_bad_arguments_change_nothing():
    w = sand_world((6, 7, 8), 9)
    field = voxfield.Field(w)
    before = field.distances()
    for kwargs, error, match in ((dict(steps=-1), ValueError, "steps"),
                                 (dict(sand=0), ValueError, "sand"),
                                 (dict(water=256), ValueError, "water"),
                                 (dict(sand=4, water=4), ValueError, "differ"),
                                 (dict(seed=-1), TypeError, ""),
                                 (dict(steps=1.5), TypeError, "")):
        with pytest.raises(error, match=match):
            field.step_sand(**kwargs)
    assert field.sand_steps == 0
    np.testing.assert_array_equal(field.world(), w)
    np.testing.assert_array_equal(field.distances(), before)
