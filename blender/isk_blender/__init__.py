"""isk for Blender: implicit skinning (Vaillant et al. 2013) of a mesh with
an Armature modifier, through the isk Python module (blender/README.md).

Build converts the mesh and its armature into an isk rig and builds the
skinner; every frame change (and every change of the armature's pose) then
deforms the mesh from the armature's pose.
The result goes into a shape key named "isk" that the add-on owns, with the
Armature modifier switched off meanwhile: the mesh's own vertices are never
written, and Remove gives everything back.
"""

bl_info = {
    "name": "isk: implicit skinning",
    "author": "isk authors",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "3D View > Sidebar > isk",
    "description": "Implicit skinning (Vaillant et al. 2013), DQS and LBS "
                   "of a mesh with an Armature modifier, through isk",
    "category": "Animation",
}

import fnmatch
import os
import sys
import tempfile
import time

import bpy
import numpy as np
from bpy.app.handlers import persistent
from bpy.props import (BoolProperty, EnumProperty, FloatProperty,
                       IntProperty, PointerProperty, StringProperty)

from . import rig_arrays

SHAPE_KEY = "isk"
BUILD_STAGES = ["partition", "sampling", "fitting", "baking", "operators",
                "iso values"]

_isk_module = None
# Object name -> _Running. Skinners live in this process only: after a file
# is opened again, Build makes them again (the field cache makes it quick).
_running = {}


def import_isk():
    """The isk module: from the preference's folder when set, else the copy
    bundled in the add-on (make_zip.py), else Python's own path."""
    global _isk_module
    if _isk_module is not None:
        return _isk_module
    folders = []
    addon = bpy.context.preferences.addons.get(__name__)
    if addon is not None and addon.preferences.module_dir:
        folders.append(bpy.path.abspath(addon.preferences.module_dir))
    bundled = os.path.join(os.path.dirname(__file__), "vendor")
    if os.path.isdir(bundled):
        folders.append(bundled)
    for folder in reversed(folders):
        if folder not in sys.path:
            sys.path.insert(0, folder)
    import isk
    _isk_module = isk
    return isk


class _Running:
    def __init__(self, skinner, armature_name, order, rest_inverse):
        self.skinner = skinner
        self.armature_name = armature_name
        self.order = order
        self.rest_inverse = rest_inverse
        self.matrices = None  # of the frame in the shape key


def parse_joint_operators(text):
    """'joint=op, joint=op' -> {joint: op}; joint names may hold spaces."""
    out = {}
    for item in text.split(","):
        item = item.strip()
        if not item:
            continue
        name, sep, op = item.rpartition("=")
        name, op = name.strip(), op.strip()
        if not sep or not name or op not in ("union", "blend", "bulge"):
            raise ValueError(f"joint operators: '{item}' is not "
                             "joint=union|blend|bulge")
        out[name] = op
    return out


def parse_untracked_joints(text, names):
    """'wing*, tail_?' -> the bone names the patterns match (fnmatch,
    case-sensitive); a pattern matching no bone is an error."""
    out = []
    for pattern in text.split(","):
        pattern = pattern.strip()
        if not pattern:
            continue
        matched = fnmatch.filter(names, pattern)
        if not matched:
            raise ValueError(f"untracked bones: '{pattern}' matches no bone")
        out += [n for n in matched if n not in out]
    return out


def cache_folder(settings):
    """The field cache: the setting, else //isk_cache beside the .blend,
    else a temporary folder for an unsaved file."""
    if settings.cache_folder:
        return bpy.path.abspath(settings.cache_folder)
    if bpy.data.filepath:
        return bpy.path.abspath("//isk_cache")
    return os.path.join(tempfile.gettempdir(), "isk_cache")


def deform(obj, depsgraph):
    """Skins the frame of `obj` into its shape key; False when it cannot."""
    running = _running.get(obj.name)
    armature_obj = bpy.data.objects.get(running.armature_name) if running \
        else None
    keys = obj.data.shape_keys
    if armature_obj is None or keys is None or SHAPE_KEY not in keys.key_blocks:
        return False
    matrices = rig_arrays.skinning_matrices(
        obj.evaluated_get(depsgraph), armature_obj.evaluated_get(depsgraph),
        running.order, running.rest_inverse)
    # The same pose again (our own mesh update, a redraw): nothing to do.
    if running.matrices is not None and np.array_equal(matrices,
                                                       running.matrices):
        return True
    running.matrices = matrices
    skinner = running.skinner
    positions, _ = skinner.deform(matrices)
    keys.key_blocks[SHAPE_KEY].data.foreach_set("co", positions.ravel())
    obj.data.update()
    obj.isk.last_frame_ms = skinner.last_frame_ms
    obj.isk.contact_count = getattr(skinner, "contact_count", 0)
    return True


@persistent
def _on_frame_change(scene, depsgraph=None):
    if depsgraph is None:
        depsgraph = bpy.context.evaluated_depsgraph_get()
    for name in list(_running):
        obj = bpy.data.objects.get(name)
        try:
            ok = obj is not None and deform(obj, depsgraph)
        except Exception as e:  # a handler must not raise on every frame
            print(f"isk: {name}: stopped: {e}", file=sys.stderr)
            ok = False
        if not ok:
            _running.pop(name, None)


@persistent
def _on_depsgraph_update(scene, depsgraph=None):
    # Posing by hand changes no frame: follow the armatures that changed.
    if not _running or depsgraph is None:
        return
    changed = {update.id.original.name for update in depsgraph.updates
               if isinstance(update.id, bpy.types.Object)}
    for name, running in list(_running.items()):
        obj = bpy.data.objects.get(name)
        if running.armature_name in changed and obj is not None:
            try:
                deform(obj, depsgraph)
            except Exception as e:
                print(f"isk: {name}: stopped: {e}", file=sys.stderr)
                _running.pop(name, None)


@persistent
def _on_load(*_):
    # Skinners belong to the file that was open: the new file's objects
    # keep their "isk" key and settings, and Build starts them again.
    _running.clear()


def restore(obj):
    """Removes the add-on's shape key (and the Basis it added) and turns the
    Armature modifier back on as it was."""
    _running.pop(obj.name, None)
    state = obj.isk
    keys = obj.data.shape_keys
    if keys is not None and SHAPE_KEY in keys.key_blocks:
        obj.shape_key_remove(keys.key_blocks[SHAPE_KEY])
        keys = obj.data.shape_keys
        if state.created_basis and keys is not None \
                and len(keys.key_blocks) == 1:
            obj.shape_key_remove(keys.key_blocks[0])
    modifier = obj.modifiers.get(state.modifier_name)
    if state.active and modifier is not None:
        modifier.show_viewport = state.modifier_show_viewport
        modifier.show_render = state.modifier_show_render
    state.active = False
    state.created_basis = False
    state.modifier_name = ""
    obj.data.update()


def _poll_mesh(context):
    obj = context.active_object
    return (obj is not None and obj.type == 'MESH'
            and context.mode == 'OBJECT')


class ISK_OT_build(bpy.types.Operator):
    """Build the implicit skinning of the active mesh from its Armature
    modifier and drive the mesh on every frame change"""
    bl_idname = "isk.build"
    bl_label = "Build implicit skinning"
    bl_options = {'REGISTER', 'UNDO'}

    @classmethod
    def poll(cls, context):
        return _poll_mesh(context) and \
            rig_arrays.armature_modifier(context.active_object) is not None

    def execute(self, context):
        obj = context.active_object
        settings = obj.isk
        try:
            isk = import_isk()
        except ImportError as e:
            self.report({'ERROR'}, f"isk: cannot import the isk module ({e}); "
                        "set its folder in the add-on's preferences")
            return {'CANCELLED'}
        modifier = rig_arrays.armature_modifier(obj)
        armature_obj = modifier.object
        wm = context.window_manager
        started = time.perf_counter()
        try:
            arrays, unweighted = rig_arrays.rig_arrays(
                obj, armature_obj, settings.max_influences)
            rig = isk.Rig.from_arrays(**arrays)
            wm.progress_begin(0.0, 1.0)
            skinner = self._make_skinner(isk, rig, settings, context)
        except (isk.Error, ValueError) as e:
            self.report({'ERROR'}, f"isk: {e}")
            return {'CANCELLED'}
        finally:
            wm.progress_end()
            if context.workspace is not None:
                context.workspace.status_text_set(None)
        order = arrays["joint_names"]
        bones = armature_obj.data.bones
        rest_inverse = np.array([np.linalg.inv(np.array(bones[n].matrix_local))
                                 for n in order])

        # Built: only now is a running skinning replaced, so a failed Build
        # leaves the object as it was.
        if settings.active:
            restore(obj)
            modifier = rig_arrays.armature_modifier(obj)
        # From here on the object changes: a shape key on top of the rest
        # mesh, and the Armature modifier off so it does not deform twice.
        settings.created_basis = obj.data.shape_keys is None
        if settings.created_basis:
            obj.shape_key_add(name="Basis", from_mix=False)
        key = obj.shape_key_add(name=SHAPE_KEY, from_mix=False)
        key.relative_key = obj.data.shape_keys.reference_key
        key.value = 1.0
        settings.modifier_name = modifier.name
        settings.modifier_show_viewport = modifier.show_viewport
        settings.modifier_show_render = modifier.show_render
        modifier.show_viewport = False
        modifier.show_render = False
        settings.active = True
        _running[obj.name] = _Running(skinner, armature_obj.name, order,
                                      rest_inverse)
        deform(obj, context.evaluated_depsgraph_get())
        for warning in list(rig.warnings) + list(getattr(skinner, "warnings",
                                                         [])):
            self.report({'WARNING'}, f"isk: {warning}")
        if unweighted:
            self.report({'WARNING'}, f"isk: {unweighted} vertices have no "
                        f"bone weight; they follow the root bone {order[0]}")
        self.report({'INFO'}, "isk: %s on %s built in %.1f s" % (
            settings.method, skinner.device, time.perf_counter() - started))
        return {'FINISHED'}

    @staticmethod
    def _make_skinner(isk, rig, settings, context):
        if settings.method != 'implicit':
            return isk.GeometricSkinner(rig, method=settings.method,
                                        device=settings.device)
        wm = context.window_manager
        workspace = context.workspace

        def progress(stage, fraction):
            done = BUILD_STAGES.index(stage) if stage in BUILD_STAGES else 0
            wm.progress_update((done + fraction) / len(BUILD_STAGES))
            if workspace is not None:
                workspace.status_text_set(
                    f"isk: building the fields: {stage} {fraction:.0%}")

        return isk.ImplicitSkinner(
            rig, device=settings.device, operator=settings.operator,
            joint_operators=parse_joint_operators(settings.joint_operators),
            untracked_joints=parse_untracked_joints(settings.untracked_joints,
                                                    rig.joint_names),
            bulge_strength=settings.bulge_strength,
            rounds=settings.rounds, sigma=settings.sigma,
            contact_angle=settings.contact_angle,
            smoothing_steps=settings.smoothing_steps,
            relaxation=settings.relaxation,
            skinned_ring_relaxation=settings.skinned_ring_relaxation,
            crease_gate=settings.crease_gate,
            volume_restore=settings.volume_restore,
            dislocation_guard=settings.dislocation_guard,
            base_skinning=settings.base_skinning, layers=settings.layers,
            rigid_pieces=settings.rigid_pieces,
            cache_dir=cache_folder(settings), progress=progress)


class ISK_OT_remove(bpy.types.Operator):
    """Stop driving the mesh: remove the isk shape key and turn the
    Armature modifier back on"""
    bl_idname = "isk.remove"
    bl_label = "Remove implicit skinning"
    bl_options = {'REGISTER', 'UNDO'}

    @classmethod
    def poll(cls, context):
        return _poll_mesh(context) and context.active_object.isk.active

    def execute(self, context):
        restore(context.active_object)
        return {'FINISHED'}


class IskSettings(bpy.types.PropertyGroup):
    method: EnumProperty(
        name="Method", default='implicit',
        items=[('implicit', "Implicit", "Implicit skinning: DQS, then the "
                "surface tracking in the fields"),
               ('dqs', "DQS", "Dual quaternion skinning"),
               ('lbs', "LBS", "Linear blend skinning")])
    device: EnumProperty(
        name="Device", default='opencl',
        items=[('opencl', "OpenCL", "$ISK_DEVICE, else the first GPU, else "
                "the first CPU device (PoCL)"),
               ('gpu', "GPU", "The first OpenCL GPU"),
               ('cpu', "CPU", "The first OpenCL CPU device"),
               ('reference', "Reference", "The single-thread CPU reference")])
    operator: EnumProperty(
        name="Operator", default='auto',
        description="The joints' composition operator",
        items=[('auto', "Auto", "Union, with the gradient-based blend at "
                "the joints of mirrored limbs (shoulders, elbows, knees...)"),
               ('union', "Union", "Max of the two fields"),
               ('blend', "Blend", "Gradient-based blend"),
               ('bulge', "Bulge", "Bulge in contact")])
    joint_operators: StringProperty(
        name="Per joint",
        description="Operators of some joints: joint=op, joint=op "
                    "(op: union, blend, bulge)")
    untracked_joints: StringProperty(
        name="Untracked bones",
        description="Bones whose parts stay where skinning puts them, as "
                    "patterns: wing*, tail_? (parts too thin for their "
                    "fields, such as wing membranes)")
    base_skinning: EnumProperty(
        name="Base", default='dqs',
        description="The geometric skinning the tracking starts from",
        items=[('dqs', "DQS", ""), ('lbs', "LBS", "")])
    bulge_strength: FloatProperty(
        name="Bulge strength", default=1.0, min=0.0, max=1.0,
        description="How much the bulge operator inflates the skin around "
                    "a contact (0: a union); joints whose operator is bulge")
    rounds: IntProperty(name="Rounds", default=8, min=0, max=100,
                        description="Surface tracking rounds per frame")
    sigma: FloatProperty(name="Sigma", default=0.35, min=0.01, max=1.0,
                         description="Step factor of the projection "
                                     "(eq. 4)")
    contact_angle: FloatProperty(
        name="Contact angle", default=55.0, min=0.1, max=180.0,
        description="Gradient jump (degrees) that stops a vertex at a "
                    "contact")
    smoothing_steps: IntProperty(name="Smoothing steps", default=8, min=0,
                                 max=100)
    relaxation: BoolProperty(name="Relaxation", default=True,
                             description="Tangential relaxation")
    skinned_ring_relaxation: BoolProperty(
        name="Skinned-ring relaxation", default=True,
        description="Relax towards the skinned ring's layout, so that a "
                    "coarse mesh's rings stay where skinning put them (off: "
                    "the paper's eq. 5 as written)")
    crease_gate: BoolProperty(
        name="Gated creases", default=True,
        description="Spread only the creases between parts whose rings the "
                    "march crushed, pushed or stretched out of their skinned "
                    "layout (off: every crease)")
    dislocation_guard: BoolProperty(
        name="Dislocation guard", default=True,
        description="Keep on skinning the skin blended between two joints "
                    "the armature does not link, where the pose moves them "
                    "apart (off: every vertex marches to its iso-surface)")
    volume_restore: FloatProperty(
        name="Volume restoration", default=3.0, min=0.0, max=3.0,
        description="The largest fraction of a vertex's inward move from "
                    "skinning given back where a closed part lost volume "
                    "(0: off; near another piece of the mesh, back to skinning "
                    "at most)")
    rigid_pieces: EnumProperty(
        name="Rigid pieces", default='auto',
        description="Pieces of the mesh bound wholly to one bone (a "
                    "robot's plates) stay where skinning puts them",
        items=[('auto', "Auto", "Rigid when such pieces hold half the "
                                "mesh or more"),
               ('rigid', "Rigid", "Always rigid"),
               ('tracked', "Tracked", "Tracked like the skin (the paper)")])
    layers: BoolProperty(
        name="Clothes layers", default=True,
        description="Leave layers of clothes (meshes that wrap a bone "
                    "around the skin) out of the fit: they follow the "
                    "skin's field")
    max_influences: IntProperty(
        name="Max influences", default=4, min=1, max=8,
        description="The largest bone weights kept per vertex")
    cache_folder: StringProperty(
        name="Field cache", subtype='DIR_PATH',
        description="Folder of the field cache; empty: //isk_cache beside "
                    "the .blend, or a temporary folder for an unsaved file")
    # Owned by the add-on.
    active: BoolProperty(default=False)
    created_basis: BoolProperty(default=False)
    modifier_name: StringProperty()
    modifier_show_viewport: BoolProperty(default=True)
    modifier_show_render: BoolProperty(default=True)
    last_frame_ms: FloatProperty(default=0.0)
    contact_count: IntProperty(default=0)


class ISK_PT_panel(bpy.types.Panel):
    bl_label = "Implicit skinning"
    bl_space_type = 'VIEW_3D'
    bl_region_type = 'UI'
    bl_category = "isk"

    @classmethod
    def poll(cls, context):
        obj = context.active_object
        return obj is not None and obj.type == 'MESH'

    def draw(self, context):
        layout = self.layout
        obj = context.active_object
        settings = obj.isk
        if rig_arrays.armature_modifier(obj) is None and not settings.active:
            layout.label(text="Needs an Armature modifier", icon='INFO')
            return
        layout.prop(settings, "method")
        layout.prop(settings, "device")
        if settings.method == 'implicit':
            layout.prop(settings, "operator")
            layout.prop(settings, "joint_operators")
            layout.prop(settings, "untracked_joints")
            layout.prop(settings, "bulge_strength")
            box = layout.box()
            box.label(text="Tracking")
            box.prop(settings, "base_skinning")
            box.prop(settings, "rounds")
            box.prop(settings, "sigma")
            box.prop(settings, "contact_angle")
            box.prop(settings, "smoothing_steps")
            box.prop(settings, "relaxation")
            box.prop(settings, "skinned_ring_relaxation")
            box.prop(settings, "crease_gate")
            box.prop(settings, "dislocation_guard")
            box.prop(settings, "volume_restore")
            box.prop(settings, "layers")
            box.prop(settings, "rigid_pieces")
            layout.prop(settings, "cache_folder")
        layout.prop(settings, "max_influences")
        row = layout.row()
        row.operator(ISK_OT_build.bl_idname, text="Build")
        row.operator(ISK_OT_remove.bl_idname, text="Remove")
        if obj.name in _running:
            layout.label(text="Last frame: %.1f ms" % settings.last_frame_ms)
            if settings.method == 'implicit':
                layout.label(text=f"Contacts: {settings.contact_count}")
        elif settings.active:
            layout.label(text="Not running since the file was opened: "
                              "Build again", icon='ERROR')


class IskPreferences(bpy.types.AddonPreferences):
    bl_idname = __name__
    module_dir: StringProperty(
        name="isk module folder", subtype='DIR_PATH',
        description="Folder holding the isk package (e.g. an install's "
                    "site-packages or build/python); empty: the copy bundled "
                    "with the add-on, else Python's path")

    def draw(self, context):
        self.layout.prop(self, "module_dir")


_classes = (IskSettings, ISK_OT_build, ISK_OT_remove, ISK_PT_panel,
            IskPreferences)


def register():
    for cls in _classes:
        bpy.utils.register_class(cls)
    bpy.types.Object.isk = PointerProperty(type=IskSettings)
    bpy.app.handlers.frame_change_post.append(_on_frame_change)
    bpy.app.handlers.load_post.append(_on_load)
    bpy.app.handlers.depsgraph_update_post.append(_on_depsgraph_update)


def unregister():
    for name in list(_running):
        obj = bpy.data.objects.get(name)
        if obj is not None:
            restore(obj)
    _running.clear()
    if _on_frame_change in bpy.app.handlers.frame_change_post:
        bpy.app.handlers.frame_change_post.remove(_on_frame_change)
    if _on_load in bpy.app.handlers.load_post:
        bpy.app.handlers.load_post.remove(_on_load)
    if _on_depsgraph_update in bpy.app.handlers.depsgraph_update_post:
        bpy.app.handlers.depsgraph_update_post.remove(_on_depsgraph_update)
    del bpy.types.Object.isk
    for cls in reversed(_classes):
        bpy.utils.unregister_class(cls)
