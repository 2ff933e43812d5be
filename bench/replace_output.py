#!/usr/bin/env python3
"""Time the ways of replacing a 512 MiB output file with a new one, on the file system of DIR.

Usage: /usr/bin/python3 bench/replace_output.py DIR

Writes DIR/t.bin once, then five times each, in turn: a new file written beside it (1 MiB writes)
and renamed over it ("rename-over", what voxfield's writer did until 0ce7183); the same with the
old file unlinked just before the rename ("unlink-then-rename", 0ce7183); the new file and the old
one swapped by renameat2's RENAME_EXCHANGE, then the old one unlinked ("exchange-then-unlink",
what the writer does now); the old file truncated and rewritten in place ("trunc-write", what
numpy.save and bench/endtoend.py's streaming do). Prints the write's time, then the time of what follows it (the rename, the unlink and the
rename, or the exchange and the unlink), and the total, in ms. On ext4 a rename over an existing file starts the new file's
writeback inside rename() (auto_da_alloc). Removes its files afterwards.
"""
import ctypes
import os
import sys
import time

AT_FDCWD, RENAME_EXCHANGE = -100, 2


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
        libc = ctypes.CDLL(None, use_errno=True)
        for mode in ["rename-over", "unlink-then-rename", "exchange-then-unlink",
                     "trunc-write"] * 5:
            t0 = time.perf_counter()
            if mode == "trunc-write":
                write(target, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, buf, mib)
                t1 = time.perf_counter()
            else:
                write(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, buf, mib)
                t1 = time.perf_counter()
                if mode == "exchange-then-unlink":
                    if libc.renameat2(AT_FDCWD, tmp.encode(), AT_FDCWD, target.encode(),
                                      RENAME_EXCHANGE) != 0:
                        sys.exit(f"renameat2: {os.strerror(ctypes.get_errno())}")
                    os.unlink(tmp)
                else:
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
