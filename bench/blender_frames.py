"""Cost of a frame change in Blender with the isk add-on against the plain
Armature modifier.

    blender -b --factory-startup --python bench/blender_frames.py -- \\
        --json /tmp/blender.json [--zip build/isk_blender.zip] \\
        [--assets CesiumMan.glb human-addon-animations.glb]

For each shared asset (from $ISK_DATA_DIR, else --data, else ../shared/data
beside the checkout), imported with Blender's glTF importer, the largest
mesh driven by an armature is played through its clip three ways: the
Armature modifier alone ("armature"), then the add-on built on it with DQS
and with implicit skinning (the add-on switches the modifier off and writes
a shape key). For each:

- frame_ms: wall time of `scene.frame_set(frame)`: the action's evaluation,
  the depsgraph (the modifier, or the shape key), and the add-on's handlers;
- handler_ms: the add-on's own handlers within it (frame_change_post and
  depsgraph_update_post, wrapped and timed here): the skinning matrices
  from the pose bones, the isk module's deform, the shape key's write;
- module_ms: the add-on's `last_frame_ms` (the isk module's C++ frame,
  without the read-back).

Medians over the clip's frames after a warm-up; the clip is played again
until at least --frames frames are timed. The add-on is installed from the
zip as Blender's Install would (its bundled isk module). Exit code 77: no
asset, or the add-on cannot be loaded.
"""

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
import zipfile

import numpy

# Debian's numpy 1.24 dropped numpy.bool, which the glTF importer of
# Blender 3.4 still uses.
numpy.bool = bool

import addon_utils  # noqa: E402
import bpy  # noqa: E402

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def arguments():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    parser = argparse.ArgumentParser(prog="blender_frames.py")
    parser.add_argument("--json", help="where the figures go")
    parser.add_argument("--zip",
                        default=os.path.join(REPO, "build", "isk_blender.zip"))
    parser.add_argument("--data", default=os.path.normpath(
        os.path.join(REPO, "..", "shared", "data")))
    parser.add_argument("--assets", nargs="+",
                        default=["CesiumMan.glb",
                                 "human-addon-animations.glb"])
    parser.add_argument("--device", default="opencl")
    parser.add_argument("--cache", default=os.path.join(
        os.environ.get("ISK_CACHE_DIR")
        or os.path.join(REPO, "build", "isk-cache"), "blender"),
        help="the add-on's field cache (builds are not timed)")
    parser.add_argument("--frames", type=int, default=60,
                        help="at least this many timed frames per mode")
    parser.add_argument("--warmup", type=int, default=5)
    return parser.parse_args(argv)


def log(message):
    print(f"blender_frames.py: {message}", file=sys.stderr, flush=True)


def install_addon(zip_path, folder):
    """The zip unpacked as Blender's Install would, then enabled."""
    with zipfile.ZipFile(zip_path) as archive:
        archive.extractall(folder)
    sys.path.insert(0, folder)
    module = addon_utils.enable("isk_blender", default_set=True,
                                handle_error=None)
    if module is None:
        raise RuntimeError("the add-on did not enable")
    return module, module.import_isk()


def import_character(asset):
    """Imports `asset` alone; its largest mesh with an Armature modifier."""
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)
    bpy.data.orphans_purge(do_recursive=True)
    bpy.ops.import_scene.gltf(filepath=asset)
    meshes = [o for o in bpy.context.scene.objects if o.type == 'MESH'
              and any(m.type == 'ARMATURE' and m.object is not None
                      for m in o.modifiers)]
    if not meshes:
        return None
    obj = max(meshes, key=lambda o: len(o.data.vertices))
    bpy.ops.object.select_all(action='DESELECT')
    obj.select_set(True)
    bpy.context.view_layer.objects.active = obj
    return obj


class HandlerClock:
    """Wraps the add-on's handlers in place to add up the time spent in
    them."""

    def __init__(self, addon):
        self.ms = 0.0
        self.lists = [(bpy.app.handlers.frame_change_post,
                       addon._on_frame_change),
                      (bpy.app.handlers.depsgraph_update_post,
                       addon._on_depsgraph_update)]
        self.wrappers = []
        for handlers, function in self.lists:
            wrapper = self._wrap(function)
            handlers[handlers.index(function)] = wrapper
            self.wrappers.append(wrapper)

    def _wrap(self, function):
        def timed(*args):
            start = time.perf_counter()
            try:
                return function(*args)
            finally:
                self.ms += (time.perf_counter() - start) * 1e3
        return timed

    def restore(self):
        for (handlers, function), wrapper in zip(self.lists, self.wrappers):
            if wrapper in handlers:
                handlers[handlers.index(wrapper)] = function


def play(obj, frames, warmup, clock):
    """Times frame_set over `frames` after `warmup` of them."""
    scene = bpy.context.scene
    frame_ms, handler_ms, module_ms = [], [], []
    for i, frame in enumerate(frames[:warmup] + frames):
        clock.ms = 0.0
        start = time.perf_counter()
        scene.frame_set(frame)
        wall = (time.perf_counter() - start) * 1e3
        if i < warmup:
            continue
        frame_ms.append(wall)
        handler_ms.append(clock.ms)
        module_ms.append(obj.isk.last_frame_ms)
    return frame_ms, handler_ms, module_ms


def median(values):
    return statistics.median(values) if values else None


def measure(asset, args, addon, clock):
    obj = import_character(asset)
    if obj is None:
        return {"asset": os.path.basename(asset),
                "error": "no mesh with an Armature modifier"}
    armature_obj = addon.rig_arrays.armature_modifier(obj).object
    action = armature_obj.animation_data.action \
        if armature_obj.animation_data else None
    start, end = (int(round(x)) for x in action.frame_range) if action \
        else (1, 1)
    clip = list(range(start, end + 1))
    frames = clip * max(1, -(-args.frames // len(clip)))
    result = {"asset": os.path.basename(asset), "object": obj.name,
              "vertices": len(obj.data.vertices),
              "bones": len(armature_obj.data.bones),
              "action": action.name if action else None,
              "clip_frames": len(clip), "fps": bpy.context.scene.render.fps}
    for mode in ("armature", "dqs", "implicit"):
        if mode != "armature":
            obj.isk.method = mode
            obj.isk.device = args.device
            obj.isk.cache_folder = args.cache
            built = time.perf_counter()
            try:
                # Headless, an operator's error report raises.
                ok = bpy.ops.isk.build() == {'FINISHED'}
                why = "Build failed"
            except RuntimeError as e:
                ok, why = False, " ".join(str(e).split())
            if not ok:
                result[mode] = {"error": why}
                continue
            result[mode + "_build_s"] = time.perf_counter() - built
            skinner = addon._running[obj.name].skinner
            result["device"] = skinner.device
        frame_ms, handler_ms, module_ms = play(obj, frames, args.warmup,
                                               clock)
        result[mode] = {"frame_ms": median(frame_ms),
                        "frames": len(frame_ms)}
        if mode != "armature":
            result[mode].update(handler_ms=median(handler_ms),
                                module_ms=median(module_ms))
            bpy.ops.isk.remove()
    base = result["armature"]["frame_ms"]
    for mode in ("dqs", "implicit"):
        r = result.get(mode, {})
        if r.get("frame_ms") and base:
            r["over_armature"] = r["frame_ms"] / base
    return result


def summary(report):
    lines = [f"Blender {report['blender']} frame changes on "
             f"{report.get('device') or '?'} (medians after "
             f"{report['warmup']} warm-up frames):"]
    for m in report["models"]:
        if "error" in m:
            lines.append(f"  {m['asset']}: {m['error']}")
            continue
        a = m["armature"]
        lines.append(f"  {m['asset']} ({m['vertices']} v, {m['bones']} "
                     f"bones, {m['clip_frames']} clip frames): Armature "
                     f"modifier {a['frame_ms']:.3f} ms")
        for mode in ("dqs", "implicit"):
            r = m.get(mode, {})
            if "error" in r:
                lines.append(f"    add-on {mode}: {r['error']}")
                continue
            lines.append(
                f"    add-on {mode:<8} frame {r['frame_ms']:8.3f} ms "
                f"({r['over_armature']:.2f}x the modifier), handlers "
                f"{r['handler_ms']:.3f} ms, module {r['module_ms']:.3f} ms")
    lines.append(f"  took {report['seconds']:.1f} s")
    return "\n".join(lines)


def main():
    started = time.perf_counter()
    args = arguments()
    data = os.environ.get("ISK_DATA_DIR") or args.data
    assets = [os.path.join(data, a) for a in args.assets]
    present = [a for a in assets if os.path.isfile(a)]
    missing = [os.path.basename(a) for a in assets if a not in present]
    if missing:
        log(f"missing in {data}: {', '.join(missing)}")
    if not present:
        log("SKIP: no asset (set ISK_DATA_DIR)")
        sys.exit(77)
    if not os.path.isfile(args.zip):
        log(f"SKIP: {args.zip} not found (cmake --build build --target "
            "isk_blender_zip)")
        sys.exit(77)
    os.makedirs(args.cache, exist_ok=True)
    work = tempfile.mkdtemp(prefix="isk-blender-frames-")
    try:
        addon, _ = install_addon(args.zip, os.path.join(work, "addons"))
    except Exception as e:  # an extension built for another Python
        log(f"SKIP: the add-on cannot load the isk module: {e}")
        sys.exit(77)
    clock = HandlerClock(addon)
    models = []
    try:
        for asset in present:
            log(os.path.basename(asset))
            models.append(measure(asset, args, addon, clock))
    finally:
        clock.restore()
    report = {"what": "blender_frames", "blender": bpy.app.version_string,
              "device": next((m["device"] for m in models if "device" in m),
                             None),
              "warmup": args.warmup, "min_frames": args.frames,
              "missing": missing, "data_dir": data,
              "date": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
              "load_avg": list(os.getloadavg()), "models": models,
              "seconds": time.perf_counter() - started}
    if args.json:
        with open(args.json, "w") as f:
            json.dump(report, f, indent=1)
    print(summary(report), flush=True)


try:
    main()
except SystemExit as e:
    # blender -b --python does not pass a script's exit code on by itself.
    sys.stdout.flush()
    os._exit(e.code if isinstance(e.code, int) else 1)
