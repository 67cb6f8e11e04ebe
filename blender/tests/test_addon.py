"""Blender.addon: the add-on in Blender 3.4, headless.

    blender -b --factory-startup --python-exit-code 1 \
        --python blender/tests/test_addon.py -- --zip build/isk_blender.zip \
        --data ../shared/data --cache build/isk-cache/blender

Installs the add-on from the zip (with its bundled isk module); for the fox
and CesiumMan, imported with Blender's glTF importer, builds DQS and then
implicit skinning on the character's mesh, plays frames of the armature's
clip and compares the deformed mesh, vertex by vertex (matched by rest
position), with the isk module's frames of the same file read by
isk.load_rig (Assimp) at the same times; checks that the mesh data stays
untouched and that Remove gives the Armature modifier back; renders one
Workbench picture of each. Exit code 77: an asset is missing.
"""

import argparse
import os
import shutil
import sys
import tempfile
import time
import types
import zipfile

import numpy

# Debian's numpy 1.24 dropped numpy.bool, which the glTF importer of
# Blender 3.4 still uses.
numpy.bool = bool

import addon_utils  # noqa: E402
import bpy  # noqa: E402
from mathutils import Vector, kdtree  # noqa: E402

# Frames on keys of both clips (the fox is keyed at 30 per second, so every
# fourth frame at 24 fps; CesiumMan at 24), where Blender, which blends
# quaternions component by component, and isk (slerp) sample the same pose.
FRAMES = [4, 12, 24, 40]
# glTF's Y-up model space into Blender's Z-up world (what the importer does).
Y_UP_TO_Z_UP = numpy.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]], numpy.float64)

STARTED = time.perf_counter()


def arguments():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    parser = argparse.ArgumentParser()
    parser.add_argument("--zip", required=True)
    parser.add_argument("--data", required=True)
    parser.add_argument("--cache", required=True)
    parser.add_argument("--device", default="opencl")
    parser.add_argument("--assets", nargs="+",
                        default=["fox-animations.glb", "CesiumMan.glb"])
    return parser.parse_args(argv)


def check(condition, message):
    if not condition:
        raise AssertionError(message)


def install_addon(zip_path, folder):
    """The zip unpacked as Blender's Install would, then enabled."""
    with zipfile.ZipFile(zip_path) as archive:
        archive.extractall(folder)
    sys.path.insert(0, folder)
    module = addon_utils.enable("isk_blender", default_set=True,
                                handle_error=None)
    check(module is not None, "the add-on did not enable")
    isk = module.import_isk()
    check(os.path.realpath(isk.__file__).startswith(os.path.realpath(folder)),
          f"isk came from {isk.__file__}, not the zip's bundled copy")
    return module, isk


def world_positions(obj, depsgraph):
    """The evaluated mesh's vertices in world space, (V, 3) float64."""
    mesh = obj.evaluated_get(depsgraph).data
    co = numpy.empty(len(mesh.vertices) * 3, numpy.float32)
    mesh.vertices.foreach_get("co", co)
    co = co.reshape(-1, 3).astype(numpy.float64)
    world = numpy.array(obj.matrix_world)
    return co @ world[:3, :3].T + world[:3, 3]


def mesh_coordinates(mesh):
    co = numpy.empty(len(mesh.vertices) * 3, numpy.float32)
    mesh.vertices.foreach_get("co", co)
    return co.reshape(-1, 3)


def match_vertices(blender_rest, isk_rest):
    """For each Blender vertex the isk vertex at the same rest position:
    Blender and Assimp split seams differently."""
    tree = kdtree.KDTree(len(isk_rest))
    for i, p in enumerate(isk_rest):
        tree.insert(p, i)
    tree.balance()
    found = [tree.find(p) for p in blender_rest]
    return (numpy.array([index for _, index, _ in found]),
            max(distance for _, _, distance in found))


def deviation(obj, reference, mapping, diagonal):
    """Max and mean distance between the evaluated mesh and the reference
    frame (isk's model space), over the rig's diagonal."""
    got = world_positions(obj, bpy.context.evaluated_depsgraph_get())
    expected = (reference.astype(numpy.float64) @ Y_UP_TO_Z_UP.T)[mapping]
    distance = numpy.linalg.norm(got - expected, axis=1) / diagonal
    return float(distance.max()), float(distance.mean())


def compare_frames(label, obj, skinner, rig, clip, fps, mapping, bound):
    worst = 0.0
    for frame in FRAMES:
        bpy.context.scene.frame_set(frame)
        reference, _ = skinner.deform(rig.clip_pose(clip, frame / fps))
        most, mean = deviation(obj, reference, mapping,
                               rig.bounding_box_diagonal)
        print(f"{label}: frame {frame} (t {frame / fps:.4f} s): max "
              f"deviation {most:.3g}, mean {mean:.3g} of the diagonal; "
              f"{obj.isk.last_frame_ms:.1f} ms, contacts "
              f"{obj.isk.contact_count}")
        worst = max(worst, most)
    print(f"{label}: max deviation over {len(FRAMES)} frames {worst:.3g} "
          f"(bound {bound:g})")
    check(worst <= bound, f"{label}: deviation {worst:.3g} > {bound:g}")
    return worst


def compare_implicit(obj, implicit, dqs, rig, clip, fps, mapping):
    """Blender's implicit frames against the module's on the Assimp rig.

    They cannot agree to float rounding: the fields are fitted to the
    normals, which Blender stores quantized as custom normals, and a vertex
    stops at a contact on a threshold, so a pose that differs by rounding
    alone (the module's own rig driven by Assimp's poses instead of
    Blender's) already moves a few vertices by a visible step. Hence a loose
    bound on the largest deviation, a tight one on the mean, and the mean
    must stay far below what implicit skinning changes from DQS, so that
    DQS frames would fail: a quarter of it on the same mesh, a half where
    Blender split seams that Assimp welds (the tracking then runs on another
    mesh).
    """
    same_mesh = len(obj.data.vertices) == rig.vertex_count
    share = 0.25 if same_mesh else 0.5
    worst = 0.0
    for frame in FRAMES:
        bpy.context.scene.frame_set(frame)
        pose = rig.clip_pose(clip, frame / fps)
        reference, _ = implicit.deform(pose)
        dqs_frame, _ = dqs.deform(pose)
        most, mean = deviation(obj, reference, mapping,
                               rig.bounding_box_diagonal)
        change = float(numpy.linalg.norm(reference - dqs_frame, axis=1).mean()
                       / rig.bounding_box_diagonal)
        print(f"implicit: frame {frame} (t {frame / fps:.4f} s): max "
              f"deviation {most:.3g}, mean {mean:.3g} of the diagonal "
              f"(implicit - DQS: mean {change:.3g}); "
              f"{obj.isk.last_frame_ms:.1f} ms, contacts "
              f"{obj.isk.contact_count}")
        check(most <= 0.05 and mean <= 2e-3 and mean <= share * change,
              f"implicit: frame {frame}: deviation max {most:.3g} mean "
              f"{mean:.3g} (implicit - DQS mean {change:.3g})")
        worst = max(worst, most)
    print(f"implicit: max deviation over {len(FRAMES)} frames {worst:.3g}")
    return worst


def check_own_frames(addon, isk, obj, armature_obj, args, diagonal):
    """The evaluated mesh is the module's frame of the add-on's own rig and
    matrices: what the frame handler writes is what Blender shows."""
    arrays, _ = addon.rig_arrays.rig_arrays(obj, armature_obj,
                                            obj.isk.max_influences)
    skinner = isk.ImplicitSkinner(isk.Rig.from_arrays(**arrays),
                                  device=args.device, cache_dir=args.cache)
    running = addon._running[obj.name]
    worst = 0.0
    for frame in FRAMES:
        bpy.context.scene.frame_set(frame)
        depsgraph = bpy.context.evaluated_depsgraph_get()
        matrices = addon.rig_arrays.skinning_matrices(
            obj.evaluated_get(depsgraph), armature_obj.evaluated_get(depsgraph),
            running.order, running.rest_inverse)
        expected, _ = skinner.deform(matrices)
        world = numpy.array(obj.matrix_world)
        expected = expected @ world[:3, :3].T + world[:3, 3]
        got = world_positions(obj, depsgraph)
        worst = max(worst, float(numpy.abs(got - expected).max()) / diagonal)
    print(f"implicit: the add-on's rig and matrices through the module: "
          f"max deviation {worst:.3g} of the diagonal")
    check(worst <= 1e-6, "the mesh is not the module's frame")


def check_hand_pose(obj, armature_obj):
    """Posing a bone by hand, without a frame change, deforms the mesh."""
    key = obj.data.shape_keys.key_blocks["isk"]
    before = numpy.empty(len(key.data) * 3, numpy.float32)
    key.data.foreach_get("co", before)
    bone = armature_obj.pose.bones[armature_obj.data.bones[1].name]
    rotation = bone.rotation_quaternion.copy()
    bone.rotation_quaternion = (0.9, 0.3, 0.2, 0.1)
    bpy.context.view_layer.update()
    after = numpy.empty_like(before)
    key.data.foreach_get("co", after)
    moved = float(numpy.abs(after - before).max())
    print(f"hand pose: the mesh moved by {moved:.3g}")
    check(moved > 1e-3, "a bone posed by hand did not move the mesh")
    bone.rotation_quaternion = rotation
    bpy.context.view_layer.update()


class _Layout:
    """Records what a panel draws (there is no UI headless)."""

    def __init__(self):
        self.items = []

    def prop(self, data, name, **_):
        check(hasattr(data, name), f"the panel draws a missing {name}")
        self.items.append(name)

    def label(self, text="", **_):
        self.items.append(text)

    def operator(self, idname, **_):
        self.items.append(idname)

    def row(self, **_):
        return self

    def box(self, **_):
        return self


def check_panel(addon, obj):
    """The sidebar panel shows the options, the buttons and the figures."""
    panel = types.SimpleNamespace(layout=_Layout())
    check(addon.ISK_PT_panel.poll(bpy.context), "no panel for the mesh")
    addon.ISK_PT_panel.draw(panel, bpy.context)
    items = panel.layout.items
    print(f"panel: {', '.join(items)}")
    for item in ("method", "operator", "joint_operators", "untracked_joints",
                 "rounds", "sigma",
                 "contact_angle", "smoothing_steps", "relaxation",
                 "skinned_ring_relaxation", "crease_gate", "dislocation_guard",
                 "volume_restore",
                 "layers", "rigid_pieces",
                 "isk.build", "isk.remove",
                 f"Contacts: {obj.isk.contact_count}"):
        check(item in items, f"the panel lacks {item}")
    check(any(item.startswith("Last frame: ") for item in items),
          "the panel lacks the frame time")


def build(obj, method, device, cache):
    obj.isk.method = method
    obj.isk.device = device
    obj.isk.cache_folder = cache
    check(bpy.ops.isk.build() == {'FINISHED'}, f"Build ({method}) failed")
    keys = obj.data.shape_keys
    check(keys is not None and "isk" in keys.key_blocks
          and keys.key_blocks["isk"].value == 1.0, "no isk shape key")
    check(not obj.modifiers["Armature"].show_viewport,
          "the Armature modifier is still on")


def render_picture(obj, folder, name):
    """A 320x240 Workbench picture of `obj` framed by the scene's camera;
    it must not be only background."""
    scene = bpy.context.scene
    corners = [obj.matrix_world @ Vector(c) for c in obj.bound_box]
    center = sum(corners, Vector()) / 8
    size = max((a - b).length for a in corners for b in corners)
    camera = scene.camera
    camera.location = center + size * Vector((1.2, -1.2, 0.6))
    camera.rotation_euler = (center - camera.location).to_track_quat(
        '-Z', 'Y').to_euler()
    scene.render.engine = 'BLENDER_WORKBENCH'
    scene.render.resolution_x, scene.render.resolution_y = 320, 240
    scene.render.resolution_percentage = 100
    scene.render.filepath = os.path.join(folder, name + ".png")
    bpy.ops.render.render(write_still=True)
    image = bpy.data.images.load(scene.render.filepath)
    pixels = numpy.array(image.pixels[:]).reshape(-1, 4)[:, :3]
    background = pixels[0]
    differ = numpy.abs(pixels - background).max(axis=1) > 0.02
    print(f"render: {scene.render.filepath}, {differ.mean():.1%} of the "
          "pixels differ from the background")
    check(differ.mean() > 0.05, "the picture is empty")
    if os.environ.get("ISK_BLENDER_TEST_PICTURES"):
        shutil.copy(scene.render.filepath,
                    os.environ["ISK_BLENDER_TEST_PICTURES"])


def main():
    args = arguments()
    data = os.environ.get("ISK_DATA_DIR") or args.data
    assets = [os.path.join(data, name) for name in args.assets]
    missing = [path for path in assets if not os.path.isfile(path)]
    if missing:
        print(f"SKIP: {', '.join(missing)} missing (set ISK_DATA_DIR)")
        sys.exit(77)
    work = tempfile.mkdtemp(prefix="isk-blender-test-")
    try:
        addon, isk = install_addon(args.zip, os.path.join(work, "addons"))
        # The factory scene's cube would hide the character in the picture.
        bpy.data.objects.remove(bpy.data.objects["Cube"])
        figures = [run(args, asset, work, addon, isk) for asset in assets]
        addon_utils.disable("isk_blender", default_set=True)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    print(f"Blender.addon: passed in {time.perf_counter() - STARTED:.1f} s")
    for asset, (dqs, implicit) in zip(args.assets, figures):
        print(f"  {asset}: dqs max deviation {dqs:.3g}, implicit max "
              f"deviation {implicit:.3g} of the diagonal")


def import_character(asset):
    """Imports `asset` into a scene holding only the camera and the light;
    returns its skinned mesh object."""
    for obj in list(bpy.data.objects):
        if obj.type not in ('CAMERA', 'LIGHT'):
            bpy.data.objects.remove(obj)
    bpy.data.orphans_purge(do_recursive=True)
    bpy.ops.import_scene.gltf(filepath=asset)
    obj = next(o for o in bpy.context.scene.objects if o.type == 'MESH'
               and any(m.type == 'ARMATURE' for m in o.modifiers))
    bpy.ops.object.select_all(action='DESELECT')
    obj.select_set(True)
    bpy.context.view_layer.objects.active = obj
    return obj


def clip_of(rig, armature_obj):
    """isk's clip of the armature's action: the importer names it
    <animation>_<armature>; an unnamed animation is isk's only clip."""
    action = armature_obj.animation_data.action.name
    named = [c.name for c in rig.clips
             if f"{c.name}_{armature_obj.name}" == action]
    check(named or len(rig.clips) == 1, f"no isk clip for {action}")
    return named[0] if named else 0


def run(args, asset, work, addon, isk):
    obj = import_character(asset)
    armature_obj = obj.modifiers["Armature"].object
    fps = bpy.context.scene.render.fps  # the importer: frame = s * fps
    rig = isk.load_rig(asset)
    clip = clip_of(rig, armature_obj)
    rest = mesh_coordinates(obj.data).copy()
    world = numpy.array(obj.matrix_world)
    blender_rest = rest.astype(numpy.float64) @ world[:3, :3].T + world[:3, 3]
    mapping, rest_distance = match_vertices(
        blender_rest, rig.rest_positions.astype(numpy.float64) @
        Y_UP_TO_Z_UP.T)
    diagonal = rig.bounding_box_diagonal
    print(f"{asset}: Blender {len(rest)} vertices, isk {rig.vertex_count}; "
          f"clip {clip} at {fps} fps; rest positions matched within "
          f"{rest_distance / diagonal:.3g} of the diagonal")
    # The two importers round the node transforms differently.
    check(rest_distance <= 5e-5 * diagonal, "rest positions do not match")
    # DQS: the same rig from Blender's arrays and from Assimp's import; only
    # float rounding of the two imports separates them.
    build(obj, "dqs", args.device, args.cache)
    dqs = isk.GeometricSkinner(rig, method="dqs", device=args.device)
    dqs_worst = compare_frames("dqs", obj, dqs, rig, clip, fps, mapping, 1e-4)
    check(numpy.array_equal(mesh_coordinates(obj.data), rest),
          "the mesh's vertices changed while the add-on drove it")

    # Remove: the Armature modifier (LBS) deforms the mesh again, as isk's
    # LBS does.
    check(bpy.ops.isk.remove() == {'FINISHED'}, "Remove failed")
    check(obj.data.shape_keys is None, "shape keys left after Remove")
    check(obj.modifiers["Armature"].show_viewport
          and obj.modifiers["Armature"].show_render,
          "the Armature modifier is not back on")
    lbs = isk.GeometricSkinner(rig, method="lbs", device=args.device)
    compare_frames("Armature modifier after Remove vs isk lbs", obj, lbs, rig,
                   clip, fps, mapping, 1e-4)

    # A bad setting is reported and changes nothing.
    obj.isk.method = "implicit"
    for setting, value, expected in (
            ("joint_operators", "no such bone=blend", "no such bone"),
            ("untracked_joints", "no such bone*",
             "'no such bone*' matches no bone")):
        setattr(obj.isk, setting, value)
        try:
            bpy.ops.isk.build()
            message = ""
        except RuntimeError as e:
            message = str(e)
        print(f"bad {setting}: {message.strip()}")
        check(expected in message and obj.data.shape_keys is None
              and obj.modifiers["Armature"].show_viewport
              and not obj.isk.active,
              "a failed Build changed the object")
        setattr(obj.isk, setting, "")

    # Implicit (compare_implicit says why its bounds are looser).
    build(obj, "implicit", args.device, args.cache)
    implicit = isk.ImplicitSkinner(
        rig, device=args.device, cache_dir=args.cache)
    implicit_worst = compare_implicit(obj, implicit, dqs, rig, clip, fps,
                                      mapping)
    check_own_frames(addon, isk, obj, armature_obj, args, diagonal)
    check_hand_pose(obj, armature_obj)
    check_panel(addon, obj)
    # Build again while running: the skinning is replaced, not stacked.
    build(obj, "implicit", args.device, args.cache)
    check([k.name for k in obj.data.shape_keys.key_blocks] == ["Basis", "isk"],
          "a second Build stacked shape keys")
    check(numpy.array_equal(mesh_coordinates(obj.data), rest),
          "the mesh's vertices changed while the add-on drove it")
    render_picture(obj, work, os.path.splitext(os.path.basename(asset))[0])

    check(bpy.ops.isk.remove() == {'FINISHED'}, "Remove failed")
    check(obj.data.shape_keys is None and not obj.isk.active,
          "Remove left the add-on's state")
    check(numpy.array_equal(mesh_coordinates(obj.data), rest),
          "the mesh's vertices changed")
    return dqs_worst, implicit_worst


main()
