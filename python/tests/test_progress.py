"""The build's progress callback: every stage's fractions grow from 0 to 1,
called on the building thread with the GIL; an exception it raises ends the
build and reaches the caller."""

import threading

import pytest

import isk
from conftest import ASSETS, BUILTIN_RIGS, load, rig_spec


def check_progress(calls):
    assert calls, "the progress callback was never called"
    stages = []
    for stage, fraction in calls:
        assert isinstance(stage, str) and isinstance(fraction, float)
        assert 0.0 <= fraction <= 1.0
        if not stages or stages[-1][0] != stage:
            stages.append((stage, []))
        stages[-1][1].append(fraction)
    for stage, fractions in stages:
        assert fractions == sorted(fractions), (stage, fractions)
        assert fractions[-1] == 1.0, (stage, fractions)
    names = [stage for stage, _ in stages]
    assert len(names) == len(set(names)), f"a stage came back: {names}"
    assert names[0] == "partition" and names[-1] == "iso values"
    return names


@pytest.mark.parametrize("device", ["opencl", "reference"])
@pytest.mark.parametrize("name", BUILTIN_RIGS + ASSETS[:1])
def test_progress_grows_per_stage(tmp_path, name, device):
    rig = load(rig_spec(name))
    calls, threads = [], set()

    def progress(stage, fraction):
        calls.append((stage, fraction))
        threads.add(threading.get_ident())

    skinner = isk.ImplicitSkinner(rig, device=device, operator="blend",
                                  progress=progress)
    names = check_progress(calls)
    assert {"sampling", "fitting", "baking"} <= set(names)
    assert threads == {threading.get_ident()}
    assert skinner.cache_origin == "off"
    skinner.run(rig.bind_pose())

    # From the field cache: "loading" replaces sampling, fitting, baking.
    for origin in ("built", "loaded"):
        calls.clear()
        skinner = isk.ImplicitSkinner(rig, device=device,
                                      cache_dir=str(tmp_path),
                                      progress=progress)
        assert skinner.cache_origin == origin
        names = check_progress(calls)
    assert "loading" in names and "fitting" not in names


def test_exception_in_progress_reaches_the_caller():
    rig = isk.builtin_rig("finger")

    def progress(stage, fraction):
        if stage == "fitting":
            raise KeyError("stop here")

    with pytest.raises(KeyError, match="stop here"):
        isk.ImplicitSkinner(rig, device="reference", progress=progress)
    # The module is still fine afterwards.
    skinner = isk.ImplicitSkinner(rig, device="reference")
    positions, _ = skinner.deform(rig.bend_pose(45))
    assert positions.shape == (rig.vertex_count, 3)
