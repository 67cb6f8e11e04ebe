#!/usr/bin/env python3
"""Per-frame cost of the isk Python module against the C++ frame it wraps.

    PYTHONPATH=build/python python3 bench/python_frames.py --json /tmp/py.json

For each model (shared assets read from $ISK_DATA_DIR, else ../shared/data
beside the checkout) and each method (implicit: isk.ImplicitSkinner, DQS:
isk.GeometricSkinner), on one OpenCL device (default: the module's
"opencl", i.e. $ISK_DEVICE, else a GPU, else PoCL):

- python_ms: wall time of `positions, normals = skinner.deform(pose)`, the
  pose (4x4 skinning matrices) computed beforehand: the matrices' conversion,
  the C++ frame, the two read-backs and the NumPy arrays.
- cpp_ms: the C++ part of that same call as the library times it: for
  implicit `last_frame_ms` (ImplicitSkinner::run: upload, DQS, tracking,
  smoothing, normals) plus `stage_times["readback"]` (readPositions and
  readNormals), i.e. the frame isk_bench's Implicit/<model>/opencl:<d> times;
  for DQS `last_frame_ms` alone (ClSkinning::run with normals: the module
  does not expose the DQS read-back time), so the DQS ratio is an upper
  bound of the Python overhead.

Both come from the same calls, so python / cpp has no drift between runs
in it. Poses step through the model's first clip by the golden ratio at 30
frames per second, as isk_bench does, and the implicit and DQS frames of a
pose run in turn, the first alternating. Figures are medians over the
frames after the warm-up. Exit code 77: the module cannot be imported.
"""
import argparse
import json
import os
import platform
import statistics
import sys
import time

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# Asset file -> the name isk_bench gives the same model.
MODELS = {"CesiumMan.glb": "CesiumMan",
          "human-addon-animations.glb": "human-addon"}


def data_dir():
    return os.environ.get("ISK_DATA_DIR") or os.path.normpath(
        os.path.join(REPO, "..", "shared", "data"))


def poses(rig, count):
    """The first `count` poses isk_bench's Implicit/ family skins."""
    clips = rig.clips
    if not clips:
        return [rig.bind_pose()] * count
    clip = clips[0]
    frames = max(1, int(clip.duration * 30.0) + 1)
    out = []
    for i in range(count):
        spread = (i * 0.6180339887498949) % 1.0
        frame = int(spread * frames) % frames
        out.append(rig.clip_pose(0, clip.start + frame / 30.0))
    return out


def median(values):
    return statistics.median(values) if values else None


def measure(isk, path, args):
    rig = isk.load_rig(path)
    started = time.perf_counter()
    implicit = isk.ImplicitSkinner(rig, device=args.device,
                                   cache_dir=args.cache)
    build_s = time.perf_counter() - started
    dqs = isk.GeometricSkinner(rig, method="dqs", device=args.device)
    frames = poses(rig, args.warmup + args.frames)
    times = {"implicit": ([], []), "dqs": ([], [])}

    def frame(name, skinner, pose, keep):
        start = time.perf_counter()
        positions, normals = skinner.deform(pose)
        wall = (time.perf_counter() - start) * 1e3
        cpp = skinner.last_frame_ms
        if name == "implicit":
            cpp += skinner.stage_times["readback"]
        if keep:
            times[name][0].append(wall)
            times[name][1].append(cpp)
        return positions, normals

    for i, pose in enumerate(frames):
        keep = i >= args.warmup
        order = [("implicit", implicit), ("dqs", dqs)]
        if i % 2:
            order.reverse()
        for name, skinner in order:
            frame(name, skinner, pose, keep)
    result = {"asset": os.path.basename(path),
              "model": MODELS.get(os.path.basename(path),
                                  os.path.splitext(os.path.basename(path))[0]),
              "vertices": rig.vertex_count, "joints": rig.joint_count,
              "device": implicit.device, "build_s": build_s,
              "cache_origin": implicit.cache_origin}
    for name, (python_ms, cpp_ms) in times.items():
        p, c = median(python_ms), median(cpp_ms)
        result[name] = {
            "python_ms": p, "cpp_ms": c,
            "python_over_cpp": p / c if p and c else None,
            "overhead_ms": p - c if p is not None and c is not None
            else None,
            "frames": len(python_ms)}
    return result


def summary(report):
    lines = [f"Python module frames on {report['device']} "
             f"({report['frames']} frames after {report['warmup']} warm-up, "
             "medians):"]
    for m in report["models"]:
        for name in ("implicit", "dqs"):
            r = m[name]
            lines.append(
                f"  {m['model']:<12} {m['vertices']:>6} v  {name:<8} "
                f"python {r['python_ms']:8.3f} ms  C++ {r['cpp_ms']:8.3f} ms"
                f"  python / C++ {r['python_over_cpp']:.2f}x  "
                f"(+{r['overhead_ms']:.3f} ms)")
    lines.append(f"  took {report['seconds']:.1f} s")
    return "\n".join(lines)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--json", help="where the figures go")
    parser.add_argument("--assets", nargs="+", default=list(MODELS),
                        help="asset files in the data folder")
    parser.add_argument("--device", default="opencl")
    parser.add_argument("--frames", type=int, default=100,
                        help="timed frames per model and method")
    parser.add_argument("--warmup", type=int, default=10)
    parser.add_argument("--cache", default=os.environ.get("ISK_CACHE_DIR")
                        or os.path.join(REPO, "build", "isk-cache"),
                        help="field cache folder (build time is not timed)")
    args = parser.parse_args()
    started = time.perf_counter()
    try:
        import isk
    except ImportError as e:
        print(f"python_frames.py: SKIP: cannot import isk ({e}); set "
              "PYTHONPATH to build/python", file=sys.stderr)
        sys.exit(77)
    folder = data_dir()
    paths = [os.path.join(folder, a) for a in args.assets]
    present = [p for p in paths if os.path.isfile(p)]
    missing = [os.path.basename(p) for p in paths if p not in present]
    models = []
    for path in present:
        print(f"python_frames.py: {os.path.basename(path)}", file=sys.stderr,
              flush=True)
        models.append(measure(isk, path, args))
    report = {"what": "python_frames", "device": models[0]["device"]
              if models else None,
              "frames": args.frames, "warmup": args.warmup,
              "missing": missing, "data_dir": folder,
              "python": platform.python_version(),
              "date": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
              "load_avg": list(os.getloadavg()),
              "models": models, "seconds": time.perf_counter() - started}
    if args.json:
        with open(args.json, "w") as f:
            json.dump(report, f, indent=1)
    if missing:
        print(f"python_frames.py: missing in {folder}: {', '.join(missing)}",
              file=sys.stderr)
    if models:
        print(summary(report))
    else:
        print("python_frames.py: no model measured")


if __name__ == "__main__":
    main()
