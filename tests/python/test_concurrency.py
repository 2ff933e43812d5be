"""Many threads calling the module at once give the single-thread results (run in a fresh
interpreter, as edt's test_concurrency.py does, so no earlier test has warmed the device)."""

import os
import subprocess
import sys
import textwrap

SCRIPT = textwrap.dedent("""
    import threading
    import numpy as np
    import voxfield
    from voxfield import ndimage

    rng = np.random.default_rng(0)
    worlds = [(rng.random((12 + i, 13, 14)) < 0.05).astype(np.uint8) for i in range(6)]
    jobs = []
    for i, w in enumerate(worlds):
        jobs.append(lambda w=w: voxfield.distance_transform(w))
        jobs.append(lambda w=w: voxfield.distance_transform(w, metric="euclidean"))
        jobs.append(lambda w=w: voxfield.distance_transform(w, metric="chebyshev",
                                                            return_indices=True)[1])
        jobs.append(lambda w=w: ndimage.distance_transform_edt(w == 0))
        jobs.append(lambda w=w: voxfield.Field(w * 3, max_distance=4).distances())
    want = [job() for job in jobs]
    errors = []
    results = {}

    def worker(t):
        try:
            for rep in range(3):
                for k in range(len(jobs)):
                    k2 = (k + 7 * t + rep) % len(jobs)
                    got = jobs[k2]()
                    if not np.array_equal(got, want[k2]):
                        errors.append(f"thread {t} job {k2} differs")
        except Exception as e:  # reported below
            errors.append(f"thread {t}: {e!r}")

    threads = [threading.Thread(target=worker, args=(t,)) for t in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    print("\\n".join(errors) if errors else "ok")
""")


def test_threads_give_single_thread_results():
    env = dict(os.environ)
    env.setdefault("VOXFIELD_DEVICE", "cpu")
    out = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True,
                         env=env, timeout=600)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok", out.stdout + out.stderr


def test_gil_is_released_while_a_device_works():
    """A pure-Python thread keeps running while another thread's transform runs."""
    script = textwrap.dedent("""
        import threading, time
        import numpy as np
        import voxfield
        w = (np.random.default_rng(1).random((96, 96, 96)) < 0.01).astype(np.uint8)
        voxfield.distance_transform(w, metric="euclidean")  # kernels built
        ticks = 0
        done = threading.Event()
        def count():
            global ticks
            while not done.is_set():
                ticks += 1
        t = threading.Thread(target=count)
        t.start()
        for _ in range(5):
            voxfield.distance_transform(w, metric="euclidean")
        done.set()
        t.join()
        print(ticks)
    """)
    env = dict(os.environ)
    env.setdefault("VOXFIELD_DEVICE", "cpu")
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         env=env, timeout=600)
    assert out.returncode == 0, out.stderr
    assert int(out.stdout) > 1000
