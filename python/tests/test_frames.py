"""The module's frames equal the C++ API's, bit for bit: LBS, DQS and
implicit skinning, on the OpenCL device and on the CPU reference, on the
procedural rigs and on two shared assets."""

import warnings

import numpy as np
import pytest

import isk
from conftest import ASSETS, BUILTIN_RIGS, load, reference_frames, rig_spec

RIGS = BUILTIN_RIGS + ASSETS
DEVICES = ["opencl", "reference"]


def make_skinner(rig, method, device, **options):
    if method == "implicit":
        return isk.ImplicitSkinner(rig, device=device, **options)
    return isk.GeometricSkinner(rig, method=method, device=device)


def assert_same_frames(skinner, reference, poses, implicit):
    assert len(poses) == len(reference.positions)
    # The frames move, so that equal frames say something.
    assert any(not np.array_equal(p, reference.positions[0])
               for p in reference.positions[1:])
    for i, pose in enumerate(poses):
        positions, normals = skinner.deform(pose)
        assert positions.dtype == np.float32 and normals.dtype == np.float32
        assert positions.flags["C_CONTIGUOUS"]
        assert np.array_equal(positions, reference.positions[i]), (
            f"frame {i}: positions differ by up to "
            f"{np.abs(positions - reference.positions[i]).max()}")
        assert np.array_equal(normals, reference.normals[i]), (
            f"frame {i}: normals differ by up to "
            f"{np.abs(normals - reference.normals[i]).max()}")
        if implicit:
            assert skinner.contact_count == reference.contacts[i]


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("method", ["lbs", "dqs", "implicit"])
@pytest.mark.parametrize("name", RIGS)
def test_clip_frames_equal_cpp(tmp_path, name, method, device):
    spec = rig_spec(name)
    frames = 3
    # The assets' fields go through the on-disk cache: the C++ program
    # builds and writes them, the module loads them.
    cache = tmp_path / "cache"
    options = [f"cache={cache}"] if name in ASSETS else []
    reference = reference_frames(tmp_path, spec, method, device, frames,
                                 *options)
    rig = load(spec)
    poses = [rig.clip_pose(0, t) for t in reference.times]
    kwargs = {"cache_dir": str(cache)} if options and method == "implicit" \
        else {}
    skinner = make_skinner(rig, method, device, **kwargs)
    if kwargs:
        assert skinner.cache_origin == "loaded"
    assert_same_frames(skinner, reference, poses, method == "implicit")


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("operator", ["blend", "bulge"])
def test_bend_pose_with_operators_equals_cpp(tmp_path, operator, device):
    # isk-skin's --clip bend:120 ends at rig.bend_pose(120).
    spec = rig_spec("arm")
    reference = reference_frames(tmp_path, spec, "implicit", device, 2,
                                 "bend=120", f"operator={operator}")
    rig = load(spec)
    poses = [rig.bind_pose(), rig.bend_pose(120)]
    skinner = isk.ImplicitSkinner(rig, device=device, operator=operator)
    assert_same_frames(skinner, reference, poses, True)


@pytest.mark.parametrize("name", BUILTIN_RIGS + ["CesiumMan.glb"])
def test_auto_operator_blends_at_the_limbs(name):
    # The default, "auto", is the union with the blend at the joints of
    # mirrored limbs: the procedural rigs (one limb) get the union's frames,
    # CesiumMan (two arms, two legs) others.
    rig = load(rig_spec(name))
    pose = rig.bend_pose(60)
    frames = {op: isk.ImplicitSkinner(rig, device="reference",
                                      **({"operator": op} if op else {}))
              .deform(pose)[0] for op in (None, "auto", "union")}
    assert np.array_equal(frames[None], frames["auto"])
    if name in BUILTIN_RIGS:
        assert np.array_equal(frames["auto"], frames["union"])
    else:
        assert not np.array_equal(frames["auto"], frames["union"])


def test_operator_controllers_shape_the_frames():
    # The bulge's strength and the blend's theta reach the operators: other
    # frames at a bend, and the fields' validation for values out of range.
    rig = isk.builtin_rig("arm")
    pose = rig.bend_pose(120)
    frames = {}
    for key, options in {"bulge": dict(operator="bulge"),
                         "bulge 0.3": dict(operator="bulge",
                                           bulge_strength=0.3),
                         "blend": dict(operator="blend"),
                         "blend 0.5": dict(operator="blend",
                                           blend_theta=0.5)}.items():
        skinner = isk.ImplicitSkinner(rig, device="reference", **options)
        frames[key] = skinner.deform(pose)[0]
    assert not np.array_equal(frames["bulge"], frames["bulge 0.3"])
    assert not np.array_equal(frames["blend"], frames["blend 0.5"])
    with pytest.raises(isk.InvalidArgumentError, match="bulge_strength"):
        isk.ImplicitSkinner(rig, device="reference", operator="bulge",
                            bulge_strength=1.5)
    with pytest.raises(isk.InvalidArgumentError, match="blend_theta"):
        isk.ImplicitSkinner(rig, device="reference", operator="blend",
                            blend_theta=-0.1)


def test_controller_for_an_operator_no_joint_uses_is_warned_about():
    # The arm has no mirrored limbs: under 'auto' it blends nowhere, so
    # blend_theta changes nothing, and the skinner says so (as isk-skin's
    # --blend-theta does); with the elbow blended it shapes the elbow.
    rig = isk.builtin_rig("arm")
    with pytest.warns(UserWarning, match="blend_theta has no effect"):
        unused = isk.ImplicitSkinner(rig, device="reference", blend_theta=0.5)
    assert "blend_theta has no effect: no joint uses blend" in unused.warnings
    with pytest.warns(UserWarning, match="bulge_strength has no effect"):
        isk.ImplicitSkinner(rig, device="reference", operator="blend",
                            bulge_strength=0.5)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        used = isk.ImplicitSkinner(rig, device="reference", blend_theta=0.5,
                                   joint_operators={"elbow": "blend"})
    assert not any("no effect" in w for w in used.warnings)
    pose = rig.bend_pose(120)
    default = isk.ImplicitSkinner(rig, device="reference",
                                  joint_operators={"elbow": "blend"})
    assert not np.array_equal(used.deform(pose)[0], default.deform(pose)[0])


def test_volume_restore_option_reaches_the_tracking():
    # The arm bent at 90 degrees: restoring gives back volume, 0 turns it
    # off (other frames), and a value out of [0, 1] is a named error.
    rig = isk.builtin_rig("arm")
    pose = rig.bend_pose(90)
    on = isk.ImplicitSkinner(rig, device="reference").deform(pose)[0]
    off = isk.ImplicitSkinner(rig, device="reference",
                              volume_restore=0.0).deform(pose)[0]
    assert not np.array_equal(on, off)
    with pytest.raises(isk.InvalidArgumentError, match="volume_restore"):
        isk.ImplicitSkinner(rig, device="reference", volume_restore=3.5)


def test_contact_bulge_option_reaches_the_tracking():
    # The finger bent 120 degrees at every joint: the bulge (on by default)
    # gives its contacts' volume back (other frames, more volume), on both
    # devices; 0 turns it off; a value out of [0, 10] is a named error.
    rig = isk.builtin_rig("finger")
    pose = rig.bend_pose(120)
    for device in ("reference", "opencl"):
        on = isk.ImplicitSkinner(rig, device=device).deform(pose)[0]
        off = isk.ImplicitSkinner(rig, device=device,
                                  contact_bulge=0.0).deform(pose)[0]
        assert not np.array_equal(on, off)
        # Not a rounding: some vertex moves by a thousandth of the size.
        rest = rig.rest_positions.reshape(-1, 3)
        moved = np.linalg.norm(on.reshape(-1, 3) - off.reshape(-1, 3), axis=1)
        assert moved.max() > 1e-3 * np.ptp(rest, axis=0).max()
    with pytest.raises(isk.InvalidArgumentError, match="contact_bulge"):
        isk.ImplicitSkinner(rig, device="reference", contact_bulge=11.0)


def test_history_tracking_option_reaches_the_skinner():
    # The leg bent to 150 degrees in 25-degree steps: the first frame is
    # the 2013 one, a later one starts from the last; after reset_history()
    # the frame is the 2013 one again; a bad mode is a named error.
    rig = isk.builtin_rig("leg")
    poses = [rig.bend_pose(d) for d in range(0, 151, 25)]
    for device in ("reference", "opencl"):
        plain = isk.ImplicitSkinner(rig, device=device)
        history = isk.ImplicitSkinner(rig, device=device, tracking="history")
        differs = False
        for i, pose in enumerate(poses):
            a, b = plain.deform(pose)[0], history.deform(pose)[0]
            if i == 0:
                assert np.array_equal(a, b), device
            differs = differs or not np.array_equal(a, b)
        assert differs, device
        history.reset_history()
        assert np.array_equal(history.deform(poses[-1])[0],
                              plain.deform(poses[-1])[0]), device
    with pytest.raises(isk.InvalidArgumentError, match="tracking"):
        isk.ImplicitSkinner(rig, device="reference", tracking="2014")


def assert_option_changes_frames(rig_name, degrees, **option):
    # Every joint of the builtin rig bent to `degrees`: the option gives
    # other frames than the defaults, on the reference and on OpenCL alike.
    rig = isk.builtin_rig(rig_name)
    pose = rig.bend_pose(degrees)
    for device in ("reference", "opencl"):
        on = isk.ImplicitSkinner(rig, device=device).deform(pose)[0]
        off = isk.ImplicitSkinner(rig, device=device, **option).deform(pose)[0]
        assert not np.array_equal(on, off), device


def test_skinned_ring_relaxation_option_reaches_the_tracking():
    # The relaxation as the paper writes it.
    assert_option_changes_frames("arm", 120, skinned_ring_relaxation=False)


def test_crease_gate_option_reaches_the_tracking():
    # Every crease spread.
    assert_option_changes_frames("leg", 120, crease_gate=False)


def test_dislocation_guard_option_reaches_the_tracking():
    # The builtin cylinder with its second joint made a root of its own (two
    # chains under one skin), the first joint turned 30 degrees: the skin
    # between the chains stays on skinning with the guard, not without; on
    # the chain as built the guard never acts.
    chain = isk.builtin_rig("cylinder")
    indices, weights = chain.weight_arrays()
    parents = chain.parents.copy()
    parents[1] = -1
    rig = isk.Rig.from_arrays(
        positions=chain.rest_positions, triangles=chain.triangles,
        parents=parents, inverse_bind_matrices=chain.inverse_bind_matrices,
        weight_indices=indices, weights=weights)
    pose = rig.bind_pose()
    turn = np.radians(30.0)
    pose[0, :3, :3] = [[np.cos(turn), -np.sin(turn), 0],
                       [np.sin(turn), np.cos(turn), 0], [0, 0, 1]]
    for device in ("reference", "opencl"):
        dqs = isk.GeometricSkinner(rig, method="dqs",
                                   device=device).deform(pose)[0]
        on = isk.ImplicitSkinner(rig, device=device).deform(pose)[0]
        off = isk.ImplicitSkinner(rig, device=device,
                                  dislocation_guard=False).deform(pose)[0]
        kept = np.all(on == dqs, axis=1)
        assert kept.any(), device
        assert not np.all(off[kept] == dqs[kept]), device
    chain_pose = chain.bend_pose(90)
    assert np.array_equal(
        isk.ImplicitSkinner(chain, device="reference").deform(chain_pose)[0],
        isk.ImplicitSkinner(chain, device="reference",
                            dislocation_guard=False).deform(chain_pose)[0])


def test_untracked_joints_stay_on_skinning():
    # The arm's hand (the wrist's part: its vertices' largest weight) left
    # on skinning: those vertices are DQS's on the CPU reference (the
    # OpenCL frame within float rounding of the march elsewhere), while the
    # rest of the arm is still tracked.
    rig = isk.builtin_rig("arm")
    pose = rig.bend_pose(90)
    indices, weights = rig.weight_arrays()
    wrist = rig.joint_names.index("wrist")
    hand = indices[np.arange(rig.vertex_count), weights.argmax(axis=1)] == wrist
    assert hand.any() and not hand.all()
    for device in ("reference", "opencl"):
        dqs = isk.GeometricSkinner(rig, method="dqs",
                                   device=device).deform(pose)[0]
        tracked = isk.ImplicitSkinner(rig, device=device).deform(pose)[0]
        untracked = isk.ImplicitSkinner(
            rig, device=device, untracked_joints=["wrist"]).deform(pose)[0]
        assert not np.array_equal(tracked[hand], dqs[hand]), device
        if device == "reference":
            assert np.array_equal(untracked[hand], dqs[hand])
        else:
            assert np.abs(untracked[hand] - dqs[hand]).max() < (
                1e-4 * rig.bounding_box_diagonal)
        assert not np.array_equal(untracked[~hand], dqs[~hand]), device


def plated_arm():
    """The procedural arm with a box bolted beside its forearm near the
    elbow, bound wholly to the elbow's joint: a rigid piece (8 vertices)."""
    rig = isk.builtin_rig("arm")
    names = rig.joint_names
    elbow, wrist = names.index("elbow"), names.index("wrist")
    binds = np.linalg.inv(rig.inverse_bind_matrices)
    a, b = binds[elbow][:3, 3], binds[wrist][:3, 3]
    axis = (b - a) / np.linalg.norm(b - a)
    side = np.cross(axis, [0.0, 0.0, 1.0])
    if np.linalg.norm(side) < 0.1:
        side = np.cross(axis, [0.0, 1.0, 0.0])
    side /= np.linalg.norm(side)
    third = np.cross(axis, side)
    at = a + 0.25 * (b - a)
    rest = rig.rest_positions
    offset = rest - at
    along = offset @ axis
    near = np.abs(along) < 0.1 * np.linalg.norm(b - a)
    radius = np.linalg.norm(offset[near] - np.outer(along[near], axis),
                            axis=1).max()
    half = 0.2 * np.linalg.norm(b - a)
    centre = at + (radius + half) * side
    corners = np.array([centre + half * (i * axis + j * side + k * third)
                        for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)],
                       dtype=np.float32)
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6),
             (0, 2, 6, 4), (1, 5, 7, 3)]
    box = [(q[0], q[1], q[2]) for q in quads] + [(q[0], q[2], q[3])
                                                 for q in quads]
    v = rig.vertex_count
    triangles = np.vstack([rig.triangles, np.array(box) + v]).astype(np.int32)
    indices, weights = rig.weight_arrays()
    box_indices = np.zeros((8, indices.shape[1]), dtype=indices.dtype)
    box_indices[:, 0] = elbow
    box_weights = np.zeros((8, weights.shape[1]), dtype=weights.dtype)
    box_weights[:, 0] = 1.0
    plated = isk.Rig.from_arrays(
        np.vstack([rest, corners]), triangles, rig.parents,
        rig.inverse_bind_matrices, np.vstack([indices, box_indices]),
        np.vstack([weights, box_weights]), joint_names=names)
    plate = np.arange(plated.vertex_count) >= v
    return plated, plate


def test_rigid_pieces_stay_where_skinning_puts_them():
    # A box bound wholly to the elbow's joint beside the forearm: kept rigid
    # ("rigid") it is DQS's on the reference (the OpenCL frame within float
    # rounding of the march elsewhere); tracked, the bend moves it; "auto"
    # tracks it here (8 vertices: far from half the mesh).
    rig, plate = plated_arm()
    pose = rig.bend_pose(90)
    for device in ("reference", "opencl"):
        dqs = isk.GeometricSkinner(rig, method="dqs",
                                   device=device).deform(pose)[0]
        frames = {mode: isk.ImplicitSkinner(
            rig, device=device, rigid_pieces=mode).deform(pose)[0]
            for mode in ("auto", "rigid", "tracked")}
        if device == "reference":
            assert np.array_equal(frames["rigid"][plate], dqs[plate])
        else:
            assert np.abs(frames["rigid"][plate] - dqs[plate]).max() < (
                1e-4 * rig.bounding_box_diagonal)
        assert not np.allclose(frames["tracked"][plate], dqs[plate]), device
        assert np.array_equal(frames["auto"], frames["tracked"]), device
        assert not np.array_equal(frames["rigid"][~plate], dqs[~plate])


def test_layers_option_reaches_the_fit():
    # The sleeved arm's sleeve is a layer: fitted with the skin
    # (layers=False) the frames differ; the plain arm has none: the same
    # frames either way.
    for name, differ in (("sleeved-arm", True), ("arm", False)):
        rig = isk.builtin_rig(name)
        pose = rig.bend_pose(90)
        a = isk.ImplicitSkinner(rig, device="reference").deform(pose)[0]
        b = isk.ImplicitSkinner(rig, device="reference",
                                layers=False).deform(pose)[0]
        assert np.array_equal(a, b) != differ, name


@pytest.mark.parametrize("name", BUILTIN_RIGS)
def test_rig_from_arrays_skins_as_the_original(name):
    rig = isk.builtin_rig(name)
    indices, weights = rig.weight_arrays()
    copy = isk.Rig.from_arrays(rig.rest_positions, rig.triangles, rig.parents,
                               rig.inverse_bind_matrices, indices, weights,
                               joint_names=rig.joint_names)
    assert copy.vertex_count == rig.vertex_count
    assert copy.joint_names == rig.joint_names
    assert np.array_equal(copy.parents, rig.parents)
    assert copy.clips == [] or len(copy.clips) == 0
    pose = rig.clip_pose(0, rig.clips[0].duration)
    for method in ("lbs", "dqs"):
        a = isk.GeometricSkinner(rig, method=method, device="reference")
        b = isk.GeometricSkinner(copy, method=method, device="reference")
        pa, na = a.deform(pose)
        pb, nb = b.deform(pose)
        assert np.array_equal(pa, pb)
        assert np.array_equal(na, nb)
    # The rest locals come back from the inverse binds: the bend agrees.
    assert np.allclose(copy.bend_pose(90), rig.bend_pose(90), atol=1e-5)


def test_bind_pose_reproduces_the_rest_mesh():
    rig = isk.builtin_rig("cylinder")
    assert np.array_equal(rig.bind_pose(),
                          np.broadcast_to(np.eye(4, dtype=np.float32),
                                          (rig.joint_count, 4, 4)))
    skinner = isk.GeometricSkinner(rig, method="dqs", device="reference")
    positions, _ = skinner.deform(rig.bind_pose())
    assert np.allclose(positions, rig.rest_positions, atol=1e-5)


@pytest.mark.parametrize("name", RIGS)
def test_skinning_matrices_from_joint_world_matrices(name):
    # A DCC hands over its joints' world matrices: times the inverse binds
    # they are the poses the skinners take.
    rig = load(rig_spec(name))
    inverse_binds = rig.inverse_bind_matrices.astype(np.float64)
    bind_world = np.linalg.inv(inverse_binds)
    assert np.allclose(rig.skinning_matrices(bind_world), rig.bind_pose(),
                       atol=1e-5)
    pose = (rig.clip_pose(0, rig.clips[0].start + rig.clips[0].duration / 2)
            if rig.clips else rig.bend_pose(60))
    world = pose.astype(np.float64) @ bind_world
    scale = max(1.0, float(np.abs(pose[:, :3, 3]).max()))
    assert np.allclose(rig.skinning_matrices(world), pose, atol=1e-5 * scale)
    with pytest.raises(ValueError, match="joint_world"):
        rig.skinning_matrices(world[:-1])


@pytest.mark.parametrize("device", DEVICES)
def test_threads_get_the_frames_of_one_thread(device):
    # Frames run without the GIL; skinners sharing a device take turns.
    import concurrent.futures

    rig = isk.builtin_rig("finger")
    poses = [rig.bend_pose(a) for a in (0, 30, 60, 90)]
    skinners = [isk.GeometricSkinner(rig, method="lbs", device=device),
                isk.GeometricSkinner(rig, method="dqs", device=device),
                isk.ImplicitSkinner(rig, device=device)]
    alone = [[s.deform(p) for p in poses] for s in skinners]

    def frames(skinner):
        return [skinner.deform(p) for p in poses]

    with concurrent.futures.ThreadPoolExecutor(len(skinners)) as pool:
        together = list(pool.map(frames, skinners))
    for a, b in zip(alone, together):
        for (pa, na), (pb, nb) in zip(a, b):
            assert np.array_equal(pa, pb) and np.array_equal(na, nb)
