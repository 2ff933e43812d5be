"""`pip install .` from a fresh clone, offline, into a temporary virtual environment (Debian's
python3 with --system-site-packages, for numpy and the build tools), then `import voxfield`
from elsewhere with no PYTHONPATH and a small check against SciPy, then the clone's whole pytest
suite run against the installed package (VOXFIELD_TEST_INSTALLED=1 makes the suite check that
`voxfield` was imported from the environment's site-packages, not from a source or build tree).

Usage: pip_install_check.py REPO WORKDIR   (CTest test `python_pip_install`)."""

import os
import shutil
import subprocess
import sys
from pathlib import Path

CHECK = """
import os, sys
import numpy as np
from scipy import ndimage as sp
import voxfield
from voxfield import ndimage
assert 'site-packages' in voxfield.__file__, voxfield.__file__
a = (np.random.default_rng(0).random((9, 10, 11)) < 0.9).astype(np.uint8)
assert np.array_equal(ndimage.distance_transform_edt(a), sp.distance_transform_edt(a))
assert np.array_equal(voxfield.distance_transform(a == 0),
                      sp.distance_transform_cdt(a, metric='taxicab'))
print('installed', voxfield.__version__, voxfield.__file__)
"""


def run(cmd, **kw):
    print("+", " ".join(str(c) for c in cmd), flush=True)
    subprocess.run(cmd, check=True, **kw)


def main():
    repo, work = Path(sys.argv[1]), Path(sys.argv[2])
    shutil.rmtree(work, ignore_errors=True)
    work.mkdir(parents=True)
    src, venv = work / "src", work / "venv"
    run(["git", "clone", "--quiet", str(repo), str(src)])
    run(["/usr/bin/python3", "-m", "venv", "--system-site-packages", str(venv)])
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    if shutil.which("ccache"):
        env["SKBUILD_CONFIGURE_OPTIONS"] = ("-DCMAKE_CXX_COMPILER_LAUNCHER=ccache "
                                            "-DCMAKE_C_COMPILER_LAUNCHER=ccache")
    run([str(venv / "bin" / "python"), "-m", "pip", "install", "--quiet",
         "--no-build-isolation", "--no-index", "."], cwd=src, env=env)
    run([str(venv / "bin" / "python"), "-c", CHECK], cwd=work, env=env)
    env["VOXFIELD_TEST_INSTALLED"] = str(venv)
    run([str(venv / "bin" / "python"), "-m", "pytest", "-q", "-p", "no:cacheprovider",
         str(src / "tests" / "python")], cwd=work, env=env)
    shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
