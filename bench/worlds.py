"""The benchmark world shared by the peer comparisons (compare_scipy.py, compare_cupy.py)."""
import numpy as np


def make_world(n, seed, spheres=16):
    """A (Z, Y, X) uint8 world: a floor at y = 0 and `spheres` random spheres, values 1..255."""
    rng = np.random.default_rng(seed)
    world = np.zeros((n, n, n), dtype=np.uint8)
    world[:, 0, :] = 1
    z, y, x = np.ogrid[0:n, 0:n, 0:n]
    for _ in range(spheres):
        cx, cy, cz = rng.integers(0, n, size=3)
        r = int(rng.integers(max(1, n // 32), max(2, n // 8) + 1))
        colour = int(rng.integers(1, 256))
        # Only touch the sphere's bounding box.
        zs = slice(max(0, cz - r), min(n, cz + r + 1))
        ys = slice(max(0, cy - r), min(n, cy + r + 1))
        xs = slice(max(0, cx - r), min(n, cx + r + 1))
        inside = (z[zs] - cz) ** 2 + (y[:, ys] - cy) ** 2 + (x[:, :, xs] - cx) ** 2 <= r * r
        world[zs, ys, xs][inside] = colour
    return world
