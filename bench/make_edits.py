#!/usr/bin/env python3
"""Writes a floor-and-spheres world (.npy) and a seeded file of brush edits for `voxfield replay`.

Usage: python3 bench/make_edits.py --size 256 --edits 200 --radius 8 --seed 6683787 \
           --world build/edits-256.npy --out build/edits-256.txt

The world: a 4-voxel floor and 16 random spheres (numpy only). The edits: spheres of the given
radius at uniformly random centres, place (random material) or erase with equal probability,
as the dissertation's benchmark mode edits a world (there: one in 12 is an erase).
"""
import argparse

import numpy as np


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--edits", type=int, default=200)
    ap.add_argument("--radius", type=int, default=8)
    ap.add_argument("--seed", type=int, default=6683787)
    ap.add_argument("--world", required=True, help="output .npy (uint8, shape Z,Y,X)")
    ap.add_argument("--out", required=True, help="output edit file")
    a = ap.parse_args()
    rng = np.random.default_rng(a.seed)
    n = a.size
    world = np.zeros((n, n, n), dtype=np.uint8)
    world[:, :4, :] = 1
    z, y, x = np.ogrid[:n, :n, :n]
    for _ in range(16):
        c = rng.integers(0, n, size=3)
        r = int(rng.integers(n // 32 + 1, n // 8 + 2))
        ball = (x - c[0]) ** 2 + (y - c[1]) ** 2 + (z - c[2]) ** 2 <= r * r
        world[ball] = int(rng.integers(1, 256))
    np.save(a.world, world)
    with open(a.out, "w") as f:
        f.write(f"# {a.edits} sphere edits of radius {a.radius} in a {n}^3 world, seed {a.seed}\n")
        for _ in range(a.edits):
            cx, cy, cz = (int(v) for v in rng.integers(0, n, size=3))
            if rng.random() < 0.5:
                f.write(f"place sphere {cx} {cy} {cz} {a.radius} {int(rng.integers(1, 256))}\n")
            else:
                f.write(f"erase sphere {cx} {cy} {cz} {a.radius}\n")


if __name__ == "__main__":
    main()
