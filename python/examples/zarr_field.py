#!/usr/bin/env python3
"""Distance field of a Zarr volume, written to Zarr, block by block with voxfield.dask.

    python3 python/examples/zarr_field.py IN.zarr OUT.zarr [--metric euclidean]
        [--max-distance 16] [--workers 2] [--device cpu]

IN.zarr holds a 3-D label volume (any integer or bool dtype, nonzero = solid; Zarr's chunks
are Dask's blocks). OUT.zarr gets the field with the same chunks: bounded (--max-distance,
blocks on the OpenCL device with halos) or unbounded (the exact separable passes). With
--workers N a distributed.LocalCluster of N single-threaded worker processes runs it, each
worker using --device (or its $VOXFIELD_DEVICE); without, Dask's threaded scheduler.
--demo N first writes a random N^3 uint8 volume to IN.zarr.
"""

import argparse
import contextlib
import os

import dask.array as da
import numpy as np
import zarr

import voxfield.dask as vd


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[1])
    p.add_argument("input")
    p.add_argument("output")
    p.add_argument("--metric", default="euclidean",
                   choices=["manhattan", "chebyshev", "euclidean"])
    p.add_argument("--max-distance", type=float, default=None)
    p.add_argument("--format", default=None)
    p.add_argument("--workers", type=int, default=0)
    p.add_argument("--device", default=None)
    p.add_argument("--demo", type=int, default=0, metavar="N")
    args = p.parse_args()
    if args.demo:
        rng = np.random.default_rng(0)
        z = zarr.open(args.input, mode="w", shape=(args.demo,) * 3, chunks=(64, 64, 64),
                      dtype=np.uint8)
        for i in range(0, args.demo, 64):
            z[i:i + 64] = (rng.random((min(64, args.demo - i), args.demo, args.demo))
                           < 0.001).astype(np.uint8)
    volume = da.from_zarr(args.input)
    field = vd.distance_transform(volume, metric=args.metric, max_distance=args.max_distance,
                                  format=args.format, device=args.device)
    with contextlib.ExitStack() as stack:
        if args.workers:
            import distributed
            cluster = stack.enter_context(distributed.LocalCluster(
                n_workers=args.workers, threads_per_worker=1, dashboard_address=None))
            client = stack.enter_context(distributed.Client(cluster))
            if args.device is None and os.environ.get("VOXFIELD_DEVICE"):
                device = os.environ["VOXFIELD_DEVICE"]
                client.run(lambda: os.environ.__setitem__("VOXFIELD_DEVICE", device))
        da.to_zarr(field, args.output, overwrite=True)
    print(f"{args.output}: {field.shape} {field.dtype}, chunks {volume.chunksize}")


if __name__ == "__main__":
    main()
