#!/usr/bin/env python3
"""Time the ways of replacing a 512 MiB output file with a new one, on the file system of DIR.

Usage: /usr/bin/python3 bench/replace_output.py DIR

Writes DIR/t.bin once, then twice each, in turn: a new file written beside it (1 MiB writes) and
renamed over it ("rename-over", what voxfield's writer did until 0ce7183); the same with the old
file unlinked just before the rename ("unlink-then-rename", what it does now); the old file
truncated and rewritten in place ("trunc-write", what numpy.save and bench/endtoend.py's streaming
do). Prints the write's time, then the time of what follows it (the rename, or the unlink and the
rename), and the total, in ms. On ext4 a rename over an existing file starts the new file's
writeback inside rename() (auto_da_alloc). Removes its files afterwards.
"""
import os
import sys
import time


def write(path, flags, buf, mib):
    fd = os.open(path, flags, 0o644)
    for _ in range(mib):
        os.write(fd, buf)
    os.close(fd)


def main():
    if len(sys.argv) != 2 or not os.path.isdir(sys.argv[1]):
        sys.exit("usage: replace_output.py DIR")
    d = sys.argv[1]
    buf = bytearray(1 << 20)
    mib = 512
    target, tmp = os.path.join(d, "t.bin"), os.path.join(d, "t.tmp")
    write(target, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, buf, mib)
    try:
        for mode in ["rename-over", "unlink-then-rename", "trunc-write"] * 2:
            t0 = time.perf_counter()
            if mode == "trunc-write":
                write(target, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, buf, mib)
                t1 = time.perf_counter()
            else:
                write(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, buf, mib)
                t1 = time.perf_counter()
                if mode == "unlink-then-rename":
                    os.unlink(target)
                os.rename(tmp, target)
            t2 = time.perf_counter()
            print(f"{mode:20s} write {1e3 * (t1 - t0):7.1f} ms, then {1e3 * (t2 - t1):7.1f} ms, "
                  f"total {1e3 * (t2 - t0):7.1f} ms")
    finally:
        for path in (target, tmp):
            if os.path.exists(path):
                os.unlink(path)


if __name__ == "__main__":
    main()
