#!/usr/bin/env python3
"""Tests of bench/run_benchmarks.py's markdown on synthetic JSON (standard
library unittest; run by CTest as BenchmarksScript.Render)."""
import os
import sys
import unittest

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import run_benchmarks  # noqa: E402


def run(name, real_time_ms, label="", **counters):
    entry = {"name": name + "/real_time", "run_name": name + "/real_time",
             "run_type": "iteration", "iterations": 10,
             "real_time": real_time_ms, "cpu_time": real_time_ms,
             "time_unit": "ms", "label": label}
    entry.update(counters)
    return entry


def implicit(model, backend, ms, vertices, **counters):
    return run(f"Implicit/{model}/{backend}/min_time:2.000", ms,
               vertices=vertices, joints=19, tracked=vertices, contact=10,
               crease=1, lost=0, upload_ms=0.01, skinning_ms=0.1,
               projection_ms=ms / 2, relaxation_ms=ms / 4,
               smoothing_ms=0.1, normals_ms=0.1, readback_ms=0.1,
               **counters)


def document(benchmarks, devices=(("cpu", "PoCL / cpu"),)):
    context = {"date": "2026-01-01T00:00:00+00:00", "num_cpus": 2,
               "host_name": "test", "mhz_per_cpu": 1000, "load_avg": [0.5]}
    for i, (kind, name) in enumerate(devices):
        context[f"isk_device_{i}"] = name
        context[f"isk_device_{i}_type"] = kind
    return {"context": context, "benchmarks": benchmarks}


class Render(unittest.TestCase):
    def test_empty_json_says_not_run(self):
        text = run_benchmarks.render(document([], devices=()), "cmd")
        self.assertIn("No OpenCL device in this run.", text)
        self.assertIn("Not run", text)
        self.assertNotIn("nan", text.lower())

    def test_levers_against_all(self):
        data = document([
            run("Levers/human-addon/all:0/min_time:2.000", 10.0,
                projection_ms=8.0, vertices=7798),
            run("Levers/human-addon/no-neighbourhoods:0/min_time:2.000", 15.0,
                projection_ms=13.0, vertices=7798),
            run("Levers/human-addon/no-occupied-cells:0/min_time:2.000", 12.5,
                projection_ms=10.5, vertices=7798),
            run("Levers/human-addon/no-neighbourhood-cells:0/min_time:2.000",
                11.0, projection_ms=9.0, vertices=7798),
        ])
        text = run_benchmarks.render(data, "cmd")
        rows = [l for l in text.splitlines()
                if l.startswith("| human-addon | no-neighbourhoods")]
        self.assertEqual(len(rows), 1, text)
        self.assertTrue(rows[0].endswith("| 1.50x | n/a |"), rows[0])
        rows = [l for l in text.splitlines()
                if l.startswith("| human-addon | no-occupied-cells")]
        self.assertEqual(len(rows), 1, text)
        self.assertTrue(rows[0].endswith("| 1.25x | n/a |"), rows[0])
        rows = [l for l in text.splitlines()
                if l.startswith("| human-addon | no-neighbourhood-cells")]
        self.assertEqual(len(rows), 1, text)
        self.assertTrue(rows[0].endswith("| 1.10x | n/a |"), rows[0])
        self.assertNotIn("nan", text.lower())

    def test_crowds_by_instance_count(self):
        data = document([
            run("Crowd/CesiumMan/x16:0/min_time:1.000", 80.0,
                vertices=41792, instances=16, crowd_ms=32.0,
                separate_ms=48.0, separate_over_crowd=1.5),
            run("Crowd/CesiumMan/x4:0/min_time:1.000", 20.0,
                vertices=10448, instances=4, crowd_ms=8.0,
                separate_ms=10.0, separate_over_crowd=1.25),
            # 4 of each of 7 characters: 28 instances.
            run("Crowd/mixed/x4:0/min_time:1.000", 120.0,
                vertices=97620, instances=28, characters=7, crowd_ms=56.0,
                separate_ms=70.0, separate_over_crowd=1.25),
        ])
        text = run_benchmarks.render(data, "cmd")
        self.assertIn("## Crowds: several characters per launch", text)
        rows = [l for l in text.splitlines() if l.startswith("| CesiumMan |")]
        self.assertEqual(rows, [
            "| CesiumMan | 4 | 10,448 | 8.000 | 2.000 | 10.00 | 1.25x |",
            "| CesiumMan | 16 | 41,792 | 32.00 | 2.000 | 48.00 | 1.50x |"],
            text)
        rows = [l for l in text.splitlines() if l.startswith("| mixed")]
        self.assertEqual(rows, [
            "| mixed (7 characters) | 28 | 97,620 | 56.00 | 2.000 | 70.00 "
            "| 1.25x |"], text)
        # A recorded run shows its crowds too.
        recorded = run_benchmarks.render(document([]), "cmd",
                                         recorded=[("gpu.json", data)])
        self.assertIn("### Crowds: several characters per launch", recorded)

    def test_levers_interleaved_use_their_own_ratio(self):
        # Interleaved runs: two frames per iteration, their own counters.
        data = document([
            run("Levers/human-addon/all:0/min_time:2.000", 30.0,
                projection_ms=8.0, vertices=7798, frame_ms=15.0,
                all_frame_ms=15.0, frame_over_all=1.0),
            run("Levers/human-addon/no-march-order:0/min_time:2.000", 20.0,
                projection_ms=9.0, vertices=7798, frame_ms=11.0,
                all_frame_ms=10.0, frame_over_all=1.1),
        ])
        text = run_benchmarks.render(data, "cmd")
        rows = [l for l in text.splitlines()
                if l.startswith("| human-addon | no-march-order")]
        self.assertEqual(len(rows), 1, text)
        self.assertIn("| 11.00 |", rows[0])
        self.assertTrue(rows[0].endswith("| 10.00 | 1.10x | n/a |"), rows[0])
        self.assertNotIn("nan", text.lower())

    def test_levers_say_how_far_the_frames_moved(self):
        # A switch that keeps the result, and a step size that does not.
        same = dict(mean_moved=0.0, max_moved=0.0, **{"moved_beyond_1e-3": 0.0})
        data = document([
            run("Levers/human-addon/no-march-order:0/min_time:2.000", 20.0,
                projection_ms=9.0, vertices=7798, frame_ms=11.0,
                all_frame_ms=10.0, frame_over_all=1.1, **same),
            run("Levers/human-addon/sigma-0.7:0/min_time:2.000", 20.0,
                projection_ms=6.0, vertices=7798, frame_ms=8.0,
                all_frame_ms=10.0, frame_over_all=0.8, mean_moved=1.84e-4,
                max_moved=1.63e-2, **{"moved_beyond_1e-3": 0.0415}),
        ])
        text = run_benchmarks.render(data, "cmd")
        rows = [l for l in text.splitlines()
                if l.startswith("| human-addon | no-march-order")]
        self.assertEqual(len(rows), 1, text)
        self.assertTrue(rows[0].endswith("| 1.10x | 0 (same frames) |"),
                        rows[0])
        rows = [l for l in text.splitlines()
                if l.startswith("| human-addon | sigma-0.7")]
        self.assertEqual(len(rows), 1, text)
        self.assertTrue(
            rows[0].endswith("| 0.80x | 1.8e-04 / 1.6e-02 / 4.15% |"),
            rows[0])

    def test_targets_from_the_figures(self):
        data = document([
            implicit("human-addon", "opencl:0", 10.0, 7798),   # 100 fps
            implicit("human-addon", "dqs:0", 0.5, 7798),
            implicit("human-addon", "reference", 20.0, 7798),
            implicit("Big", "opencl:0", 40.0, 150000),
            implicit("Big", "dqs:0", 10.0, 150000),            # 4x: met
            implicit("Big", "reference", 50.0, 150000),        # 1.25x
        ])
        text = run_benchmarks.render(data, "cmd")
        rows = [l for l in text.splitlines() if l.startswith("| implicit")]
        human = next(r for r in rows if "human-addon (7,798 v)" in r)
        self.assertIn("100 fps", human)
        self.assertTrue(human.endswith("| met |"), human)
        ratio = next(r for r in rows if "implicit / DQS" in r)
        self.assertIn("4.0x", ratio)
        self.assertTrue(ratio.endswith("| met |"), ratio)
        speedup = next(r for r in rows if "over the 1-thread" in r)
        self.assertIn("1.25x", speedup)
        self.assertIn("not met", speedup)
        gpu = next(r for r in rows if "GPU" in r)
        self.assertIn("no GPU device in this run", gpu)
        # The paper's Armadillo sits beside the 150k model.
        armadillo = next(l for l in text.splitlines()
                         if l.startswith("| Armadillo"))
        self.assertIn("| Big |", armadillo)
        self.assertIn("29.0x", armadillo)

    def test_paired_frames_give_the_implicit_over_dqs_ratio(self):
        # Separate runs say 4x; the frames timed side by side say 6x: the
        # paired ratio is the one reported, in the targets, the model table
        # and beside the paper's Armadillo.
        data = document([
            implicit("Big", "opencl:0", 40.0, 150000),
            implicit("Big", "dqs:0", 10.0, 150000),
            run("Implicit/Big/paired:0/min_time:2.000", 50.0,
                vertices=150000, joints=19, implicit_ms=42.0, dqs_ms=7.0,
                implicit_over_dqs=6.0),
        ])
        text = run_benchmarks.render(data, "cmd")
        target = next(l for l in text.splitlines()
                      if l.startswith("| implicit / DQS"))
        self.assertIn("| 6.0x (paired: 42.00 / 7.000 ms) | **not met** |",
                      target)
        model = next(l for l in text.splitlines()
                     if l.startswith("| Big |") and l.count("|") > 12)
        self.assertIn("| 6.0x (paired: 42.00 / 7.000 ms) |", model)
        self.assertNotIn("| 4.0x |", model)
        armadillo = next(l for l in text.splitlines()
                         if l.startswith("| Armadillo"))
        self.assertTrue(armadillo.endswith("| 6.0x |"), armadillo)

    def test_a_gpu_device_is_measured(self):
        data = document([implicit("Big", "opencl:1", 2.0, 150000),
                         implicit("Big", "dqs:1", 1.0, 150000)],
                        devices=(("cpu", "PoCL / cpu"),
                                 ("gpu", "Vendor / GPU")))
        text = run_benchmarks.render(data, "cmd")
        gpu = next(l for l in text.splitlines()
                   if l.startswith("| implicit, ~170k vertices, GPU"))
        self.assertIn("Vendor / GPU", gpu)
        self.assertIn("500 fps", gpu)
        self.assertTrue(gpu.endswith("| met |"), gpu)
        self.assertNotIn("No GPU device", text)

    def test_a_recorded_gpu_run_fills_the_gpu_targets(self):
        here = document([implicit("Big", "opencl:0", 50.0, 150000),
                         implicit("Big", "dqs:0", 5.0, 150000)])
        there = document([implicit("Big", "opencl:0", 4.0, 150000),
                          implicit("Big", "dqs:0", 1.0, 150000)],
                         devices=(("gpu", "Vendor / GPU"),))
        text = run_benchmarks.render(here, "cmd",
                                     recorded=[("bench/results/x.json",
                                                there)])
        rows = [l for l in text.splitlines()
                if "recorded run `bench/results/x.json`" in l]
        self.assertEqual(len(rows), 2, text)
        self.assertIn("| 250 fps | {} |".format("**not met**"), rows[0])
        self.assertIn("| 4.0x | met |", rows[1])
        # This run's own ratio (10x) stays in the table, not met.
        self.assertIn("| 10.0x | **not met** |", text)
        self.assertIn("## Recorded run: Vendor / GPU", text)
        self.assertIn("#### Vendor / GPU (OpenCL device 0)", text)
        self.assertNotIn("nan", text.lower())

    def test_stage_table_times_every_stage_the_run_timed(self):
        # 10 ms: projection 5, relaxation 2.5, volume 1, strain limit 1, and
        # 0.41 in the small stages of implicit(): 0.09 ms is not in a stage.
        data = document([implicit("Big", "opencl:0", 10.0, 1000,
                                  volume_ms=1.0, strain_limit_ms=1.0),
                         implicit("Old", "opencl:0", 10.0, 1000)])
        text = run_benchmarks.render(data, "cmd")
        header = next(l for l in text.splitlines()
                      if l.startswith("| model | frame ms | upload |"))
        self.assertIn("| smoothing | volume | strain_limit | normals |",
                      header)
        big = next(l for l in text.splitlines()
                   if l.startswith("| Big | 10.00 |"))
        self.assertIn("| 1.000 (10%) | 1.000 (10%) |", big)
        self.assertTrue(big.endswith("| 1% |"), big)
        # A run recorded before the two stages had counters says n/a.
        old = next(l for l in text.splitlines()
                   if l.startswith("| Old | 10.00 |"))
        self.assertIn("| n/a | n/a |", old)

    def test_a_recorded_run_of_paired_scaling_frames_has_its_rows(self):
        # A recorded GPU run with only Scaling/.../paired: the rows take the
        # paired frames' own times; the stage columns say n/a.
        here = document([implicit("Big", "opencl:0", 50.0, 150000)])
        there = document([
            run("Scaling/vertices/160k/paired:0/min_time:1.000", 2.0,
                vertices=160000, joints=4, implicit_ms=1.5, dqs_ms=0.5,
                implicit_over_dqs=3.0)],
            devices=(("gpu", "Vendor / GPU"),))
        text = run_benchmarks.render(here, "cmd",
                                     recorded=[("bench/results/x.json",
                                                there)])
        recorded = text[text.index("## Recorded run: Vendor / GPU"):]
        self.assertIn("#### Vertex count, Vendor / GPU (OpenCL device 0)",
                      recorded)
        row = next(l for l in recorded.splitlines()
                   if l.startswith("| 160k |"))
        self.assertIn("| 160,000 | 4 | 1.500 | 667 | 0.500 | "
                      "3.0x (paired: 1.500 / 0.500 ms) | n/a |", row)
        self.assertTrue(row.endswith("| 9 | n/a |"), row)
        self.assertIn("#### Bone count: not run", recorded)

    def test_partial_families_and_google_benchmark_suffixes(self):
        data = document([
            run("Frame/opencl:0/M/dqs", 2.0, vertices=1000, upload_ms=0.1,
                skinning_ms=0.5, normals_ms=0.5, readback_ms=0.1),
            run("Frame/reference/M/dqs", 4.0, vertices=1000),
            run("OperatorTable/blend/bake/iterations:3", 400.0, table_MiB=32),
            run("OperatorTable/blend/cached-load/iterations:10", 20.0,
                table_MiB=32),
            run("ProgramBuild/fields/cold:0/iterations:2", 900.0),
            run("ProgramBuild/fields/warm:0/iterations:3", 25.0),
            run("Scaling/joints/8/implicit:0/min_time:1.000", 10.0,
                vertices=40000, joints=8, projection_ms=5, relaxation_ms=2,
                smoothing_ms=1, normals_ms=0.5, contact=3),
            run("FieldBuild/M/threads:1", 100.0, vertices=1000, joints=4,
                fields=4, field_MiB=2),
            run("FieldBuild/M/cached-load", 10.0, uncached_ms=100.0),
            run("Import/M/in-process", 4.0, vertices=2612),
            run("Import/M/isolated", 32.0, vertices=2612, in_process_ms=4.1,
                overhead_ms=28.0),
        ])
        text = run_benchmarks.render(data, "cmd")
        self.assertIn("| M | 1,000 | dqs | 2.000 | 500 | 4.000 | 2.00x", text)
        self.assertIn("| blend | 32 | 400.0 | 20.00 | 20.0x |", text)
        self.assertIn("| fields | PoCL / cpu | 900.0 | 25.00 | n/a |", text)
        self.assertIn("| 8 | 40,000 | 8 | 10.00 |", text)
        self.assertIn("## Implicit skinning per frame\n\nNot run", text)
        self.assertIn("### Vertex count: not run", text)
        # threads:1 is ours, not Google Benchmark's.
        self.assertIn("| M | 1,000 | 4 | 4 | 2.0 | 100.0 |", text)
        # The cached load and its speed-up over the build.
        self.assertIn("| 10.00 (10.0x) |", text)
        # The isolated import beside the in-process one.
        self.assertIn("| M | 2,612 | 4.000 | 32.00 | 8.0x |", text)

    def test_python_and_blender_figures(self):
        python = {"device": "PoCL / cpu", "frames": 60, "warmup": 5,
                  "wall_seconds": 2.0, "missing": [],
                  "command": "PYTHONPATH=build/python python3 "
                             "bench/python_frames.py --json OUT.json",
                  "models": [{
                      "model": "CesiumMan", "vertices": 2612,
                      "device": "PoCL / cpu",
                      "implicit": {"python_ms": 2.2, "cpp_ms": 2.0,
                                   "python_over_cpp": 1.1,
                                   "overhead_ms": 0.2},
                      "dqs": {"python_ms": 0.3, "cpp_ms": 0.2,
                              "python_over_cpp": 1.5, "overhead_ms": 0.1}}]}
        blender = {"blender": "3.4.1", "device": "PoCL / cpu",
                   "wall_seconds": 6.0, "warmup": 5, "min_frames": 60,
                   "missing": ["human-addon-animations.glb"],
                   "models": [{
                       "asset": "CesiumMan.glb", "vertices": 3273,
                       "bones": 19, "clip_frames": 48,
                       "armature": {"frame_ms": 2.0},
                       "dqs": {"frame_ms": 4.0, "over_armature": 2.0,
                               "handler_ms": 1.0, "module_ms": 0.2},
                       "implicit": {"error": "Build failed"}}]}
        data = document([implicit("CesiumMan", "opencl:0", 2.5, 2612),
                         implicit("CesiumMan", "dqs:0", 0.25, 2612)])
        data["isk_python_blender"] = {"python": python, "blender": blender}
        text = run_benchmarks.render(data, "cmd")
        section = text[text.index("## Python and Blender"):]
        self.assertIn("`PYTHONPATH=build/python python3 "
                      "bench/python_frames.py --json OUT.json`", section)
        self.assertIn("| CesiumMan | 2,612 | implicit | 2.200 | 2.000 | "
                      "1.10x | 0.200 | 2.500 | 0.88x |", section)
        self.assertIn("| CesiumMan | 2,612 | DQS | 0.300 | 0.200 | 1.50x | "
                      "0.100 | 0.250 | 1.20x |", section)
        rows = [l for l in section.splitlines()
                if l.startswith("| CesiumMan.glb")]
        self.assertEqual(rows, [
            "| CesiumMan.glb (3,273 v, 19 bones, 48 clip frames) | Armature "
            "modifier | 2.000 | 1.00x |  |  |  |",
            "| CesiumMan.glb (3,273 v, 19 bones, 48 clip frames) | add-on, "
            "DQS | 4.000 | 2.00x | 1.000 | 0.200 | 3.000 |",
            "| CesiumMan.glb (3,273 v, 19 bones, 48 clip frames) | add-on, "
            "implicit | Build failed | n/a | n/a | n/a | n/a |"], section)
        self.assertIn("Assets missing: human-addon-animations.glb.", section)
        self.assertNotIn("nan", text.lower())

    def test_python_and_blender_skipped_or_absent(self):
        data = document([])
        text = run_benchmarks.render(data, "cmd")
        self.assertIn("## Python and Blender\n\nNot run", text)
        data["isk_python_blender"] = {
            "python": {"skipped": "no isk module in build/python"},
            "blender": {"failed": "exit code 1"}}
        text = run_benchmarks.render(data, "cmd")
        self.assertIn("Python module: skipped: no isk module in "
                      "build/python.", text)
        self.assertIn("Blender: failed: exit code 1.", text)
        # An --only-python JSON gives its section alone.
        data["context"]["isk_only_python"] = True
        text = run_benchmarks.render(data, "cmd --only-python")
        self.assertTrue(text.startswith(
            "# Benchmarks: Python and Blender only"), text)
        self.assertIn("Blender: failed: exit code 1.", text)
        self.assertNotIn("## Targets", text)

    def test_failed_runs_are_listed(self):
        failed = run("Implicit/M/opencl:0", 1.0)
        failed.update(error_occurred=True,
                      error_message="boom | in\nkernel " + "x" * 400)
        text = run_benchmarks.render(document([failed]), "cmd")
        row = next(l for l in text.splitlines() if "boom" in l)
        self.assertIn("boom \\| in kernel x", row)
        self.assertTrue(row.endswith(" ... |"), row)


if __name__ == "__main__":
    unittest.main()
