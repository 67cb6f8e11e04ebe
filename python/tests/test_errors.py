"""Bad input gives isk.Error (isk.InvalidArgumentError for a bad argument,
also a ValueError) with a message naming what is wrong, never a crash."""

import numpy as np
import pytest

import isk


def cylinder_arrays():
    rig = isk.builtin_rig("cylinder")
    indices, weights = rig.weight_arrays()
    return rig, dict(positions=rig.rest_positions, triangles=rig.triangles,
                     parents=rig.parents,
                     inverse_bind_matrices=rig.inverse_bind_matrices,
                     weight_indices=indices, weights=weights)


def from_arrays_error(**changes):
    _, arrays = cylinder_arrays()
    arrays.update(changes)
    with pytest.raises(isk.InvalidArgumentError) as info:
        isk.Rig.from_arrays(**arrays)
    assert info.value.code == "invalid_argument"
    return str(info.value)


def test_error_classes():
    assert issubclass(isk.Error, RuntimeError)
    assert issubclass(isk.InvalidArgumentError, isk.Error)
    assert issubclass(isk.InvalidArgumentError, ValueError)


def test_wrong_shapes_are_named():
    rig, arrays = cylinder_arrays()
    message = from_arrays_error(positions=arrays["positions"][:, :2])
    assert "positions" in message and "shape" in message and "(3554, 2)" \
        in message
    message = from_arrays_error(weights=arrays["weights"][:-1])
    assert "weights" in message and "shape" in message
    message = from_arrays_error(inverse_bind_matrices=np.zeros((3, 3, 3)))
    assert "inverse_bind_matrices" in message and "shape" in message


def test_wrong_dtypes_are_named():
    _, arrays = cylinder_arrays()
    message = from_arrays_error(
        triangles=arrays["triangles"].astype(np.float64))
    assert "triangles" in message and "integers" in message
    message = from_arrays_error(positions=np.full((4, 3), "x"))
    assert "positions" in message and "dtype" in message
    message = from_arrays_error(parents=None)
    assert "parents" in message


def test_non_finite_values_are_named():
    _, arrays = cylinder_arrays()
    positions = arrays["positions"].copy()
    positions[7, 1] = np.nan
    message = from_arrays_error(positions=positions)
    assert "positions" in message and "row 7" in message \
        and "not finite" in message
    weights = arrays["weights"].copy()
    weights[3, 0] = np.inf
    message = from_arrays_error(weights=weights)
    assert "vertex 3" in message


def test_indices_out_of_range_are_named():
    _, arrays = cylinder_arrays()
    triangles = arrays["triangles"].copy()
    triangles[5, 2] = 10**6
    message = from_arrays_error(triangles=triangles)
    assert "triangle 5" in message and "out of range" in message
    triangles = triangles.astype(np.int64)
    triangles[5, 2] = 2**40
    message = from_arrays_error(triangles=triangles)
    assert "triangles" in message and "32 bits" in message
    indices = arrays["weight_indices"].copy()
    indices[9, 0] = 3
    message = from_arrays_error(weight_indices=indices)
    assert "vertex 9" in message and "joint index 3" in message \
        and "out of range" in message
    message = from_arrays_error(parents=np.array([-1, 2, 1]))
    assert "parents must precede children" in message


def test_weights_not_summing_to_one_are_named():
    _, arrays = cylinder_arrays()
    weights = arrays["weights"].copy()
    weights[11] *= 0.5
    message = from_arrays_error(weights=weights)
    assert "vertex 11" in message and "summing to 0.5" in message


def test_non_rigid_bind_is_named():
    _, arrays = cylinder_arrays()
    binds = arrays["inverse_bind_matrices"].copy()
    binds[1, 0, 0] = 2.0
    message = from_arrays_error(inverse_bind_matrices=binds)
    assert "joint 'joint_1' (1)" in message and "non-rigid" in message
    binds = arrays["inverse_bind_matrices"].copy()
    binds[2, 3, 0] = 1.0
    message = from_arrays_error(inverse_bind_matrices=binds)
    assert "matrix 2" in message and "last row" in message


def test_joint_names_must_match_the_joints():
    message = from_arrays_error(joint_names=["a", "b"])
    assert "joint_names" in message and "2 names for 3 joints" in message


@pytest.mark.parametrize("device", ["opencl", "reference"])
def test_bad_poses_are_named(device):
    rig = isk.builtin_rig("cylinder")
    for skinner in (isk.GeometricSkinner(rig, device=device),
                    isk.ImplicitSkinner(rig, device=device)):
        with pytest.raises(isk.InvalidArgumentError, match="before"):
            skinner.positions()
        with pytest.raises(isk.InvalidArgumentError,
                           match=r"matrices: expected shape \(3, 4, 4\), "
                                 r"got \(2, 4, 4\)"):
            skinner.run(rig.bind_pose()[:2])
        with pytest.raises(isk.InvalidArgumentError, match="matrices"):
            skinner.run("not a pose")
        pose = rig.bind_pose()
        pose[1, 0, 3] = np.nan
        with pytest.raises(isk.InvalidArgumentError, match="finite"):
            skinner.run(pose)
        # Still usable after the errors.
        positions, _ = skinner.deform(rig.bind_pose())
        assert positions.shape == (rig.vertex_count, 3)


def test_bad_options_are_named():
    rig = isk.builtin_rig("arm")
    with pytest.raises(isk.InvalidArgumentError, match="device"):
        isk.ImplicitSkinner(rig, device="tpu")
    with pytest.raises(isk.InvalidArgumentError,
                       match="operator: expected 'auto', 'union'"):
        isk.ImplicitSkinner(rig, operator="glue")
    with pytest.raises(isk.InvalidArgumentError,
                       match="no joint named 'knee'"):
        isk.ImplicitSkinner(rig, joint_operators={"knee": "blend"})
    with pytest.raises(isk.InvalidArgumentError, match="blend"):
        isk.ImplicitSkinner(rig, joint_operators={rig.joint_names[1]: "x"})
    with pytest.raises(isk.InvalidArgumentError,
                       match="untracked_joints: no joint named 'knee'"):
        isk.ImplicitSkinner(rig, untracked_joints=["knee"])
    with pytest.raises(isk.InvalidArgumentError,
                       match="untracked_joints: expected a list"):
        isk.ImplicitSkinner(rig, untracked_joints="wrist")
    with pytest.raises(isk.InvalidArgumentError,
                       match="rigid_pieces: expected 'auto', 'rigid' or "
                             "'tracked', got 'bolted'"):
        isk.ImplicitSkinner(rig, rigid_pieces="bolted")
    with pytest.raises(isk.InvalidArgumentError, match="tracking"):
        isk.ImplicitSkinner(rig, sigma=2.0)
    with pytest.raises(isk.InvalidArgumentError, match="tracking"):
        isk.ImplicitSkinner(rig, rounds=-1)
    with pytest.raises(isk.InvalidArgumentError, match="method"):
        isk.GeometricSkinner(rig, method="slerp")
    with pytest.raises(isk.InvalidArgumentError, match="progress"):
        isk.ImplicitSkinner(rig, progress=3)


def test_bad_rig_inputs_are_named(tmp_path):
    with pytest.raises(isk.Error) as info:
        isk.load_rig(str(tmp_path / "missing.glb"))
    assert "missing.glb" in str(info.value)
    bad = tmp_path / "bad.glb"
    bad.write_bytes(b"glTF not really")
    with pytest.raises(isk.Error) as info:
        isk.load_rig(str(bad))
    assert "bad.glb" in str(info.value)
    with pytest.raises(isk.InvalidArgumentError, match="cylinder"):
        isk.builtin_rig("tentacle")
    rig = isk.builtin_rig("cylinder")
    with pytest.raises(isk.InvalidArgumentError, match="out of range"):
        rig.clip_pose(5, 0.0)
    with pytest.raises(isk.InvalidArgumentError, match="'bend'"):
        rig.clip_pose("walk", 0.0)
    with pytest.raises(isk.InvalidArgumentError, match="time"):
        rig.clip_pose(0, float("nan"))
    with pytest.raises(isk.InvalidArgumentError, match="degrees"):
        rig.bend_pose(200)


def test_bad_quality_input_is_named():
    rig = isk.builtin_rig("cylinder")
    with pytest.raises(isk.InvalidArgumentError, match="positions"):
        isk.quality(rig, rig.rest_positions[:10])
    positions = rig.rest_positions
    positions[0, 0] = np.inf
    with pytest.raises(isk.InvalidArgumentError, match="row 0"):
        isk.quality(rig, positions)
