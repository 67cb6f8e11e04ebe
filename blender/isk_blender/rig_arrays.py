"""Blender mesh + armature -> the arrays of isk.Rig.from_arrays, and the
armature's pose -> the skinning matrices the skinners take.

Everything is in the mesh object's space: the rest positions are the mesh's
(its reference shape key when it has shape keys), and a bone's matrices go
from armature space to object space through the two objects' world matrices,
as the Armature modifier does.
"""

import bpy
import numpy as np


def armature_modifier(obj):
    """The first Armature modifier of `obj` that has an armature, or None."""
    for modifier in obj.modifiers:
        if modifier.type == 'ARMATURE' and modifier.object is not None:
            return modifier
    return None


def joint_order(armature):
    """The armature's (bpy.types.Armature) bone names, every parent before
    its children (isk's joint order); Blender's bone order does not promise
    it."""
    order = []

    def visit(bone):
        order.append(bone.name)
        for child in bone.children:
            visit(child)

    for bone in armature.bones:
        if bone.parent is None:
            visit(bone)
    return order


def armature_to_object(obj, armature_obj):
    """Armature space -> the mesh object's space, now."""
    return np.array(obj.matrix_world.inverted() @ armature_obj.matrix_world,
                    dtype=np.float64)


def rest_positions(mesh):
    """(V, 3) float32: the reference shape key when there are shape keys
    (the add-on's own key lives on top of it), else the vertices."""
    count = len(mesh.vertices)
    out = np.empty(count * 3, dtype=np.float32)
    if mesh.shape_keys is not None:
        mesh.shape_keys.reference_key.data.foreach_get("co", out)
    else:
        mesh.vertices.foreach_get("co", out)
    return out.reshape(count, 3)


def triangles_and_normals(mesh):
    """(F, 3) int32 triangles and (V, 3) float32 vertex normals, from a
    triangulated copy of the mesh: the user's mesh is left as it is. The
    normals are the mean of each vertex's loop normals (the custom normals a
    glTF or FBX import stores, else the shading's); isk fits the fields to
    them."""
    copy = mesh.copy()
    try:
        copy.calc_loop_triangles()
        tris = np.empty(len(copy.loop_triangles) * 3, dtype=np.int32)
        copy.loop_triangles.foreach_get("vertices", tris)
        copy.calc_normals_split()
        loop_normals = np.empty(len(copy.loops) * 3, dtype=np.float32)
        copy.loops.foreach_get("normal", loop_normals)
        loop_vertices = np.empty(len(copy.loops), dtype=np.int32)
        copy.loops.foreach_get("vertex_index", loop_vertices)
        vertex_normals = np.empty(len(copy.vertices) * 3, dtype=np.float32)
        copy.vertices.foreach_get("normal", vertex_normals)
    finally:
        bpy.data.meshes.remove(copy)
    normals = np.zeros((len(mesh.vertices), 3), dtype=np.float64)
    np.add.at(normals, loop_vertices, loop_normals.reshape(-1, 3))
    length = np.linalg.norm(normals, axis=1)
    # A vertex on no face, or whose loop normals cancel: its own normal.
    fallback = length < 1e-6
    normals[fallback] = vertex_normals.reshape(-1, 3)[fallback]
    length[fallback] = 1.0
    return tris.reshape(-1, 3), (normals / length[:, None]).astype(np.float32)


def joint_weights(obj, names, max_influences):
    """(indices, weights, unweighted): the vertex groups named after deform
    bones, as the Armature modifier reads them, the `max_influences` largest
    per vertex, normalized. A vertex with no such weight follows the first
    root joint (isk needs weights summing to 1); `unweighted` counts them."""
    joint_of_group = {}
    for group in obj.vertex_groups:
        if group.name in names:
            joint_of_group[group.index] = names[group.name]
    mesh = obj.data
    count = len(mesh.vertices)
    indices = np.full((count, max_influences), -1, dtype=np.int32)
    weights = np.zeros((count, max_influences), dtype=np.float32)
    unweighted = 0
    for vertex in mesh.vertices:
        pairs = {}
        for element in vertex.groups:
            joint = joint_of_group.get(element.group)
            if joint is not None and element.weight > 0.0:
                pairs[joint] = pairs.get(joint, 0.0) + element.weight
        best = sorted(pairs.items(), key=lambda p: -p[1])[:max_influences]
        total = sum(w for _, w in best)
        if total <= 0.0:
            best, total = [(0, 1.0)], 1.0
            unweighted += 1
        for k, (joint, weight) in enumerate(best):
            indices[vertex.index, k] = joint
            weights[vertex.index, k] = weight / total
    return indices, weights, unweighted


def rig_arrays(obj, armature_obj, max_influences):
    """The keyword arguments of isk.Rig.from_arrays for `obj` skinned by
    `armature_obj`, plus `unweighted` (vertices given to the root)."""
    armature = armature_obj.data
    order = joint_order(armature)
    deform = {name: j for j, name in enumerate(order)
              if armature.bones[name].use_deform}
    index = {name: j for j, name in enumerate(order)}
    parents = np.array(
        [index[armature.bones[n].parent.name] if armature.bones[n].parent
         else -1 for n in order], dtype=np.int32)
    to_object = armature_to_object(obj, armature_obj)
    binds = np.array([to_object @ np.array(armature.bones[n].matrix_local)
                      for n in order])
    indices, weights, unweighted = joint_weights(obj, deform, max_influences)
    tris, normals = triangles_and_normals(obj.data)
    return dict(
        positions=rest_positions(obj.data),
        triangles=tris,
        normals=normals,
        parents=parents,
        inverse_bind_matrices=np.linalg.inv(binds).astype(np.float32),
        weight_indices=indices,
        weights=weights,
        joint_names=order,
        source=obj.name,
    ), unweighted


def skinning_matrices(obj, armature_obj, order, rest_inverse):
    """(J, 4, 4) float32 in the mesh object's space: pose_bone.matrix @
    inverse(bone.matrix_local) per joint (armature space), moved into the
    object's space with the objects' current world matrices. `obj` and
    `armature_obj` are the evaluated objects of the frame; `rest_inverse` is
    the stacked inverse matrix_local of the joints in `order`."""
    to_object = armature_to_object(obj, armature_obj)
    bones = armature_obj.pose.bones
    pose = np.array([np.array(bones[name].matrix) for name in order])
    skin = np.einsum("ij,njk,nkl,lm->nim", to_object, pose, rest_inverse,
                     np.linalg.inv(to_object))
    return skin.astype(np.float32)
