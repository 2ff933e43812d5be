"""The benchmark worlds shared by the peer comparisons (compare_scipy.py, compare_cupy.py).

make_world(n, seed) is the floor-and-spheres world every earlier result used. WORLDS names the
benchmark set of issue 26, each made by make_named(name, n, seed) as a (Z, Y, X) uint8 array of
about n^3 voxels (values 1..255 solid, 0 empty):

  random-0.01% .. random-50%  solid voxels drawn independently with that probability
  clustered                   a few hundred dense blobs (radius 2..n/16) around random centres
  terrain                     a smooth heightmap along y (sum of random sines), solid below it
  floor-spheres               make_world: a floor at y = 0 and 16 random spheres
  long-z, long-y, long-x      sparse random 0.1% in a box 64 x 64 voxels across and n^3 / 4096
                              long along one axis (4096 at n = 256)
"""
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


def random_world(shape, density, seed):
    """Solid voxels (values 1..255) drawn independently with probability `density`."""
    rng = np.random.default_rng(seed)
    solid = rng.random(shape, dtype=np.float32) < density
    colours = rng.integers(1, 256, size=int(solid.sum()), dtype=np.uint8)
    world = np.zeros(shape, dtype=np.uint8)
    world[solid] = colours
    return world


def clustered_world(n, seed, blobs=300):
    """Dense blobs of radius 2..n/16 around random centres."""
    rng = np.random.default_rng(seed)
    world = np.zeros((n, n, n), dtype=np.uint8)
    for _ in range(blobs):
        c = rng.integers(0, n, size=3)
        r = int(rng.integers(2, max(3, n // 16) + 1))
        lo = np.maximum(c - r, 0)
        hi = np.minimum(c + r + 1, n)
        z, y, x = np.ogrid[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]]
        # Half the voxels of the ball: a porous cluster rather than a sphere.
        inside = ((z - c[0]) ** 2 + (y - c[1]) ** 2 + (x - c[2]) ** 2 <= r * r)
        inside = inside & (rng.random(inside.shape) < 0.5)
        world[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]][inside] = int(rng.integers(1, 256))
    return world


def terrain_world(n, seed):
    """Solid below a smooth height h(x, z) = sum of random sines, between n/8 and n/2."""
    rng = np.random.default_rng(seed)
    z, x = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    h = np.zeros((n, n))
    for k in range(6):
        f = rng.uniform(0.5, 4.0) * 2 * np.pi / n
        a = rng.uniform(0, 2 * np.pi)
        h += np.sin(f * (np.cos(a) * x + np.sin(a) * z) + rng.uniform(0, 2 * np.pi)) / (k + 1)
    h = (h - h.min()) / max(h.max() - h.min(), 1e-9)
    height = (n / 8 + h * (n / 2 - n / 8)).astype(np.int64)
    y = np.arange(n)[None, :, None]
    world = (y < height[:, None, :]).astype(np.uint8)
    world *= np.uint8(rng.integers(1, 256))
    return world


def long_shape(n, axis):
    """(Z, Y, X) of n^3 voxels, 64 x 64 across and n^3 / 4096 along `axis` (0 z, 1 y, 2 x)."""
    shape = [64, 64, 64]
    shape[axis] = max(1, n ** 3 // 4096)
    return tuple(shape)


DENSITIES = {"random-0.01%": 1e-4, "random-0.1%": 1e-3, "random-1%": 1e-2, "random-10%": 0.1,
             "random-50%": 0.5}
WORLDS = list(DENSITIES) + ["clustered", "terrain", "floor-spheres", "long-z", "long-y", "long-x"]


def make_named(name, n, seed):
    """The world `name` of WORLDS at size n (about n^3 voxels), seeded."""
    if name in DENSITIES:
        return random_world((n, n, n), DENSITIES[name], seed)
    if name == "clustered":
        return clustered_world(n, seed)
    if name == "terrain":
        return terrain_world(n, seed)
    if name == "floor-spheres":
        return make_world(n, seed)
    if name in ("long-z", "long-y", "long-x"):
        return random_world(long_shape(n, "zyx".index(name[-1])), 1e-3, seed)
    raise ValueError(f"unknown world '{name}'; expected one of {', '.join(WORLDS)}")
