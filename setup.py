"""`pip install .`: the Python package `voxfield` built by scikit-build driving the project's
CMake (VOXFIELD_PYTHON_ONLY: core, cl and the extension only). Offline with Debian's tools:
pip install --no-build-isolation --no-index . (python3-skbuild, python3-pybind11, cmake)."""

import re
from pathlib import Path

from skbuild import setup

ROOT = Path(__file__).resolve().parent
VERSION = re.search(r"project\(voxfield VERSION ([0-9.]+)",
                    (ROOT / "CMakeLists.txt").read_text()).group(1)

setup(
    name="voxfield",
    version=VERSION,
    description="Exact distance fields of voxel worlds on OpenCL devices, "
                "with a scipy.ndimage drop-in and Dask support",
    long_description=(ROOT / "README.md").read_text(encoding="utf-8"),
    long_description_content_type="text/markdown",
    python_requires=">=3.9",
    install_requires=["numpy"],
    extras_require={"dask": ["dask[array]"]},
    packages=["voxfield"],
    package_dir={"": "python"},
    package_data={"voxfield": ["*.pyi", "py.typed"]},
    cmake_install_dir="python",
    cmake_install_target="voxfield_install_python",
    cmake_args=["-DCMAKE_BUILD_TYPE=Release", "-DVOXFIELD_PYTHON_ONLY=ON"],
    zip_safe=False,
)
