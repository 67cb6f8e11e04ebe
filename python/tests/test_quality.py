"""isk.quality: the rest pose keeps the volume and makes no new
intersecting pair; a bend measures what isk-skin's report measures."""

import math

import numpy as np
import pytest

import isk
from conftest import ASSETS, BUILTIN_RIGS, load, rig_spec

KEYS = {"self_intersections", "new_self_intersections",
        "rest_self_intersections", "volume_ratio", "covered_volume_ratio",
        "rest_volume",
        "edge_strain_mean", "edge_strain_max", "crumpled_edges",
        "contact_region_vertices",
        "dqs_distance_mean", "dqs_distance_max", "parts"}


@pytest.mark.parametrize("name", BUILTIN_RIGS + ASSETS)
def test_rest_pose_keeps_everything(name):
    rig = load(rig_spec(name))
    q = isk.quality(rig, rig.rest_positions)
    assert set(q) == KEYS
    assert q["new_self_intersections"] == 0
    assert q["self_intersections"] == q["rest_self_intersections"]
    if q["volume_ratio"] is not None:
        assert q["volume_ratio"] == pytest.approx(1.0, abs=1e-12)
        assert q["covered_volume_ratio"] == 1.0
    else:
        assert name in ASSETS, "every procedural rig is closed"
    assert q["edge_strain_max"] == 0.0
    assert q["crumpled_edges"] == 0
    assert q["dqs_distance_max"] == 0.0
    # The rest pose skinned on the device measures the same.
    skinner = isk.GeometricSkinner(rig, method="dqs", device="opencl")
    positions, _ = skinner.deform(rig.bind_pose())
    q = isk.quality(rig, positions)
    assert q["new_self_intersections"] == 0
    if q["volume_ratio"] is not None:
        assert q["volume_ratio"] == pytest.approx(1.0, abs=1e-4)


@pytest.mark.parametrize("name", BUILTIN_RIGS)
def test_bend_measures(name):
    rig = isk.builtin_rig(name)
    pose = rig.bend_pose(120)
    dqs, _ = isk.GeometricSkinner(rig, method="dqs",
                                  device="reference").deform(pose)
    implicit, _ = isk.ImplicitSkinner(rig, device="reference").deform(pose)
    q = isk.quality(rig, implicit, dqs_positions=dqs)
    assert 0.5 < q["volume_ratio"] < 1.5
    assert q["edge_strain_max"] > 0.0
    assert q["dqs_distance_max"] > 0.0 and math.isfinite(
        q["dqs_distance_max"])
    # Against itself DQS is at distance 0.
    q = isk.quality(rig, dqs, dqs_positions=dqs)
    assert q["dqs_distance_max"] == 0.0


def test_uniform_scale():
    rig = isk.builtin_rig("cylinder")
    q = isk.quality(rig, 2.0 * rig.rest_positions)
    assert q["volume_ratio"] == pytest.approx(8.0, rel=1e-6)
    assert q["edge_strain_mean"] == pytest.approx(1.0, rel=1e-5)
    assert q["new_self_intersections"] == 0


def test_a_vertex_through_the_skin_is_a_new_pair():
    rig = isk.builtin_rig("cylinder")
    positions = rig.rest_positions
    # A side vertex halfway along, pushed through to the other side.
    side = np.argmin(np.abs(positions[:, 0] - 4.0) + np.abs(
        positions[:, 2]) - positions[:, 1])
    positions[side, 1] = -1.5
    q = isk.quality(rig, positions)
    assert q["new_self_intersections"] > 0
    # Per part, against the rest pose as the DQS frame: the pushed vertex's
    # part alone moved (its edges strain the part beside it too).
    q = isk.quality(rig, positions, dqs_positions=rig.rest_positions)
    parts = q["parts"]
    assert len(parts) == 2
    assert {p["joint"] for p in parts} <= set(rig.joint_names)
    assert all(p["dqs_edge_strain_mean"] == 0 for p in parts)
    assert all(p["edge_strain_mean"] > 0 for p in parts)
    moved = [p["dqs_distance_max"] for p in parts]
    assert sorted(moved)[0] == 0 and sorted(moved)[1] > 0
    # The new pairs the pushed vertex makes are its part's (DQS, the rest
    # pose, has none).
    assert all(p["dqs_new_pairs"] == 0 for p in parts)
    assert max(p["new_pairs"] for p in parts) > 0
    assert all(p["new_pairs"] <= q["new_self_intersections"] for p in parts)


def isk_skin_exe():
    import os
    from conftest import REPO
    exe = os.environ.get("ISK_SKIN_EXE") or str(
        REPO / "build" / "samples" / "isk-skin" / "isk-skin")
    assert os.path.isfile(exe), f"{exe} is missing: build isk-skin"
    return exe


@pytest.mark.parametrize("method", ["lbs", "dqs"])
@pytest.mark.parametrize("name", BUILTIN_RIGS + ASSETS)
def test_measures_equal_isk_skin_report(tmp_path, name, method):
    # The same frames (CPU reference) measured by isk-skin's report.
    import json
    import subprocess

    spec = rig_spec(name)
    frames = 3
    clip = "bend:120" if name in BUILTIN_RIGS else "0"
    report = tmp_path / "report.json"
    result = subprocess.run(
        [isk_skin_exe(), spec, "--method", method, "--device", "reference",
         "--clip", clip, "--frames", str(frames), "--report", str(report)],
        capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    expected = json.loads(report.read_text())["quality"]["frames"]

    rig = load(spec)
    skinner = isk.GeometricSkinner(rig, method=method, device="reference")
    dqs = isk.GeometricSkinner(rig, method="dqs", device="reference")
    clip_quality = isk.SkinQuality(rig)
    for i in range(frames):
        if name in BUILTIN_RIGS:
            pose = rig.bend_pose(120 * i / (frames - 1)) if i else \
                rig.bind_pose()
        else:
            c = rig.clips[0]
            pose = rig.clip_pose(0, c.start + i * c.duration / (frames - 1))
        positions, _ = skinner.deform(pose)
        reference = dqs.deform(pose)[0] if method == "lbs" else None
        q = isk.quality(rig, positions, dqs_positions=reference)
        # The clip's measure: the same, plus the jitter over three frames.
        c = clip_quality.measure(positions, dqs_positions=reference)
        assert set(c) == set(q) | {"jitter_mean", "jitter_max",
                                   "lost_vertices"}
        for key in ("self_intersections", "new_self_intersections",
                    "crumpled_edges", "contact_region_vertices",
                    "lost_vertices"):
            assert q.get(key, 0) == expected[i][key], (i, key)
            assert c[key] == expected[i][key], (i, key)
        for key in ("volume_ratio", "covered_volume_ratio",
                    "edge_strain_mean", "edge_strain_max",
                    "dqs_distance_mean", "dqs_distance_max", "jitter_mean",
                    "jitter_max"):
            for measured in ([q, c] if key in q else [c]):
                if expected[i][key] is None:
                    assert measured[key] is None, (i, key)
                else:
                    assert measured[key] == pytest.approx(
                        expected[i][key], rel=1e-9, abs=1e-12), (i, key)
    assert (c["jitter_max"] is not None) == (frames >= 3)
    summary = clip_quality.summary()
    assert summary["frames"] == frames
    assert summary["new_self_intersections_total"] == sum(
        f["new_self_intersections"] for f in expected)
    assert summary["crumpled_edges_total"] == sum(
        f["crumpled_edges"] for f in expected)
    assert summary["crumpled_edges_max"] == max(
        f["crumpled_edges"] for f in expected)
    # Per part: the report's quality.parts (by excess strain) by joint.
    parts = json.loads(report.read_text())["quality"]["parts"]
    assert {p["joint"] for p in summary["parts"]} == {p["joint"] for p in parts}
    by_joint = {p["joint"]: p for p in parts}
    for part in summary["parts"]:
        reported = by_joint[part["joint"]]
        assert part["edges"] == reported["edges"]
        assert part["new_pairs"] == reported["new_pairs"]
        assert part["dqs_new_pairs"] == reported["dqs_new_pairs"]
        assert part["crumpled_edges"] == reported["crumpled_edges"]
        assert part["dqs_crumpled_edges"] == reported["dqs_crumpled_edges"]
        for key in ("edge_strain_mean", "dqs_edge_strain_mean",
                    "dqs_distance_max"):
            assert part[key] == pytest.approx(reported[key], rel=1e-9,
                                              abs=1e-12), (part["joint"], key)
        if method == "dqs":
            assert part["edge_strain_mean"] == part["dqs_edge_strain_mean"]
