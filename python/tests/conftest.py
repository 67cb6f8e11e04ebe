"""What the Python tests share: the data folder, the C++ reference frames."""

import os
import pathlib
import subprocess

import numpy as np
import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]

# The procedural rigs every property is checked on; the assets add to them.
BUILTIN_RIGS = ["cylinder", "finger", "arm", "sleeved-arm", "leg"]
ASSETS = ["CesiumMan.glb", "fox-animations.glb"]


def data_dir():
    """ISK_DATA_DIR, else the build's default (CTest passes it), else
    ../shared/data beside the checkout."""
    folder = os.environ.get("ISK_DATA_DIR") or os.environ.get(
        "ISK_DEFAULT_DATA_DIR") or str(REPO.parent / "shared" / "data")
    return pathlib.Path(folder)


def asset_path(name):
    """The asset's path, or a pytest skip naming what is missing."""
    path = data_dir() / name
    if not path.is_file():
        pytest.skip(f"{name}: not in the data folder {data_dir()} "
                    "(set ISK_DATA_DIR); the procedural rigs cover the same "
                    "checks")
    return path


def rig_spec(name):
    """builtin:NAME for a procedural rig, else the asset's path."""
    return f"builtin:{name}" if name in BUILTIN_RIGS else str(asset_path(name))


def load(spec):
    import isk
    if spec.startswith("builtin:"):
        return isk.builtin_rig(spec[len("builtin:"):])
    return isk.load_rig(spec)


def reference_exe():
    exe = os.environ.get("ISK_PY_REFERENCE_FRAMES") or str(
        REPO / "build" / "python" / "isk_py_reference_frames")
    assert os.path.isfile(exe), (
        f"{exe} is missing: build the isk_py_reference_frames target "
        "(or run the tests through CTest)")
    return exe


class Frames:
    """Frames written by isk_py_reference_frames."""

    def __init__(self, path):
        data = path.read_bytes()
        frames, vertices = np.frombuffer(data, "<i4", 2)
        self.times, self.contacts, self.positions, self.normals = [], [], [], []
        offset = 8
        floats = int(vertices) * 3
        for _ in range(int(frames)):
            self.times.append(float(np.frombuffer(data, "<f8", 1, offset)[0]))
            self.contacts.append(int(np.frombuffer(data, "<i4", 1,
                                                   offset + 8)[0]))
            offset += 12
            for out in (self.positions, self.normals):
                out.append(np.frombuffer(data, "<f4", floats,
                                         offset).reshape(-1, 3))
                offset += 4 * floats
        assert offset == len(data), "trailing bytes in the reference frames"


def reference_frames(tmp_path, spec, method, device, frames, *options):
    """The C++ program's frames of `spec` (a rig spec, see rig_spec)."""
    out = tmp_path / f"reference-{method}-{device}.bin"
    result = subprocess.run(
        [reference_exe(), spec, method, device, str(frames), str(out),
         *options], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    return Frames(out)
