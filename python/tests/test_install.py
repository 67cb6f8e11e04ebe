"""cmake --install puts the package into the prefix's site-packages, where
it imports and skins without the build tree."""

import os
import pathlib
import re
import shutil
import subprocess
import sys

from conftest import REPO


def test_installed_package_imports_and_skins(tmp_path):
    build = pathlib.Path(os.environ.get("ISK_BUILD_DIR", REPO / "build"))
    cmake = os.environ.get("ISK_CMAKE") or shutil.which("cmake")
    site = os.environ.get("ISK_PYTHON_INSTALL_DIR")
    if not site:
        cache = (build / "CMakeCache.txt").read_text()
        site = next(line.split("=", 1)[1] for line in cache.splitlines()
                    if line.startswith("ISK_PYTHON_INSTALL_DIR:"))
    assert re.fullmatch(r"lib\w*/python3\.\d+/site-packages", site), site
    prefix = tmp_path / "prefix"
    result = subprocess.run([cmake, "--install", str(build), "--prefix",
                             str(prefix)], capture_output=True, text=True)
    assert result.returncode == 0, result.stdout + result.stderr
    package = prefix / site / "isk"
    for name in ("__init__.py", "__init__.pyi", "_isk.pyi", "py.typed"):
        assert (package / name).is_file(), name
    assert list(package.glob("_isk*.so")), "the extension is not installed"

    script = (
        "import isk, numpy as np\n"
        "rig = isk.builtin_rig('cylinder')\n"
        "skinner = isk.GeometricSkinner(rig, device='reference')\n"
        "positions, normals = skinner.deform(rig.bend_pose(90))\n"
        "assert positions.shape == (rig.vertex_count, 3)\n"
        "print(isk.__file__)\n")
    env = dict(os.environ, PYTHONPATH=str(prefix / site))
    result = subprocess.run([sys.executable, "-c", script], env=env,
                            cwd=tmp_path, capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip().startswith(str(package))
