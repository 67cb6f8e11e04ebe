#!/usr/bin/env python3
"""Tests of quality/run_quality.py without the C++ programs: the targets on
made-up reports, the cases, the markdown, the files, and one whole run with
stand-ins for isk-skin and isk-frame-pictures (standard library unittest;
`python3 quality/test_run_quality.py`, `python3 -m pytest quality/` or
`python3 quality/run_quality.py --self-test`)."""
import contextlib
import io
import json
import os
import re
import stat
import sys
import tempfile
import unittest

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import run_quality as rq  # noqa: E402


def read(path):
    with open(path) as f:
        return f.read()


@contextlib.contextmanager
def quiet():
    """The script's progress on stderr, kept out of the test output."""
    with contextlib.redirect_stderr(io.StringIO()):
        yield


def frame(new=0, volume=1.0, strain_mean=0.01, strain_max=0.1,
          distance=0.001, jitter=None, lost=0, crumpled=0):
    return {"self_intersections": new + 2, "new_self_intersections": new,
            "volume_ratio": volume, "covered_volume_ratio": volume,
            "edge_strain_mean": strain_mean,
            "edge_strain_max": strain_max, "crumpled_edges": crumpled,
            "contact_region_vertices": 0,
            "dqs_distance_mean": distance / 2, "dqs_distance_max": distance,
            "jitter_mean": None if jitter is None else jitter / 2,
            "jitter_max": jitter, "lost_vertices": lost}


def report(frames, method="implicit", rest_pose_error=0.0, clip="walk"):
    """A report shaped like isk-skin's, its summary made from `frames`."""
    volumes = [f["volume_ratio"] for f in frames
               if f["volume_ratio"] is not None]
    jitters = [f["jitter_max"] for f in frames if f["jitter_max"] is not None]
    news = [f["new_self_intersections"] for f in frames]
    worst = max(range(len(frames)), key=lambda k: (news[k], -k))
    q = {"volume_ratio": ({"min": min(volumes), "max": max(volumes)}
                          if volumes else None),
         "covered_volume_ratio": ({"min": min(volumes), "max": max(volumes)}
                                  if volumes else None),
         "rest_pose_error": rest_pose_error,
         "self_intersections": {"max": max(news), "total": sum(news),
                                "at_rest": 2, "counted": "pairs (test)"},
         "edge_strain": {"mean": sum(f["edge_strain_mean"] for f in frames)
                         / len(frames),
                         "max": max(f["edge_strain_max"] for f in frames)},
         "crumpled_edges": {
             "max": max(f["crumpled_edges"] for f in frames),
             "total": sum(f["crumpled_edges"] for f in frames)},
         "dqs_distance_max": max(f["dqs_distance_max"] for f in frames),
         "jitter_max": max(jitters) if jitters else None,
         "lost_vertices_max": max(f["lost_vertices"] for f in frames),
         "worst_frame": worst, "measures": "per frame: things (test)",
         "frames": frames}
    if method == "implicit":
        q["contact_vertices"] = 5.0
    return {"input": "x", "vertices": 100, "triangles": 196,
            "frames": len(frames), "method": method, "clip": clip,
            "device": {"platform": "PoCL", "name": "cpu", "version": "3"},
            "frame_ms": {"median": 1.5, "p95": 2.0, "min": 1.0},
            "quality": q}


def ok(frames, **kw):
    return {"ok": True, "report": report(frames, **kw), "error": None}


def failed(error="isk-skin: error: frame 3: vertex 7 is not finite"):
    return {"ok": False, "report": None, "error": error}


def dqs_frames(news=(0, 5, 10), volumes=(1.0, 0.95, 0.90)):
    return [frame(new=n, volume=v, strain_mean=0.02, strain_max=0.3,
                  distance=0.0) for n, v in zip(news, volumes)]


class PairsTarget(unittest.TestCase):
    def test_fewer_pairs_on_every_frame_is_met(self):
        status, detail = rq.target_pairs(
            ok(dqs_frames()), ok([frame(new=n) for n in (0, 1, 2)]))
        self.assertEqual(status, rq.MET)
        self.assertIn("sum 3 vs DQS 15", detail)

    def test_one_frame_worse_names_it(self):
        status, detail = rq.target_pairs(
            ok(dqs_frames()), ok([frame(new=n) for n in (0, 9, 2)]))
        self.assertEqual(status, rq.NOT_MET)
        self.assertIn("frame 1: 9 vs DQS 5", detail)

    def test_ten_percent_of_a_large_sum(self):
        dqs = ok(dqs_frames(news=(50, 60, 90)))  # sum 200
        within = ok([frame(new=n) for n in (5, 5, 10)])  # 20 = 10%
        over = ok([frame(new=n) for n in (10, 10, 10)])  # 30 > 20
        self.assertEqual(rq.target_pairs(dqs, within)[0], rq.MET)
        status, detail = rq.target_pairs(dqs, over)
        self.assertEqual(status, rq.NOT_MET)
        self.assertIn("sum 30 > 10% of DQS's 200", detail)

    def test_small_sums_need_no_ten_percent(self):
        dqs = ok(dqs_frames(news=(30, 30, 39)))  # 99 < 100
        self.assertEqual(rq.target_pairs(
            dqs, ok([frame(new=n) for n in (30, 30, 39)]))[0], rq.MET)

    def test_failed_runs(self):
        status, detail = rq.target_pairs(ok(dqs_frames()), failed())
        self.assertEqual(status, rq.NOT_MET)
        self.assertIn("not finite", detail)
        self.assertEqual(rq.target_pairs(failed(), ok(dqs_frames()))[0],
                         rq.NA)


class VolumeTarget(unittest.TestCase):
    def test_within_dqs_or_two_percent(self):
        imp = ok([frame(volume=v) for v in (0.99, 0.985, 0.91)])
        self.assertEqual(rq.target_volume(ok(dqs_frames()), imp)[0], rq.MET)

    def test_worse_than_both_names_the_frame(self):
        imp = ok([frame(volume=v) for v in (1.0, 0.97, 0.85)])
        status, detail = rq.target_volume(ok(dqs_frames()), imp)
        self.assertEqual(status, rq.NOT_MET)
        self.assertIn("frame 2: |0.8500 - 1| = 0.1500", detail)
        # frame 1: |0.97 - 1| = 0.03 <= max(|0.95 - 1|, 0.02): fine.
        self.assertIn("1 frame, worst frame 2", detail)
        self.assertIn("> max(|0.9000 - 1|, 0.02) = 0.1000", detail)

    def test_floor_applies_where_dqs_keeps_volume(self):
        imp = ok([frame(volume=v) for v in (1.0, 0.975, 0.9)])
        dqs = ok(dqs_frames(volumes=(1.0, 1.0, 0.9)))
        status, detail = rq.target_volume(dqs, imp)
        self.assertEqual(status, rq.NOT_MET)
        self.assertIn("1 frame, worst frame 1", detail)

    def test_covered_volume_judged_on_its_own_ratio(self):
        # DQS's skin passes through itself: its signed volume stays at 1
        # while its covered volume falls as far as implicit's.
        dqs_f = dqs_frames(volumes=(1.0, 1.0, 1.0))
        for f, covered in zip(dqs_f, (1.0, 0.95, 0.9)):
            f["covered_volume_ratio"] = covered
        imp = ok([frame(volume=v) for v in (1.0, 0.95, 0.9)])
        self.assertEqual(rq.target_volume(ok(dqs_f), imp)[0], rq.NOT_MET)
        self.assertEqual(rq.target_covered(ok(dqs_f), imp)[0], rq.MET)

    def test_open_mesh_is_na(self):
        imp = ok([frame(volume=None) for _ in range(3)])
        dqs = ok([frame(volume=None) for _ in range(3)])
        self.assertEqual(rq.target_volume(dqs, imp)[0], rq.NA)


class ShapeTarget(unittest.TestCase):
    def test_met(self):
        imp = ok([frame(strain_mean=0.015, strain_max=0.35, distance=0.004)
                  for _ in range(3)])
        self.assertEqual(rq.target_shape(ok(dqs_frames()), imp)[0], rq.MET)

    def test_mean_strain_above_dqs(self):
        imp = ok([frame(strain_mean=0.03, strain_max=0.3) for _ in range(3)])
        status, detail = rq.target_shape(ok(dqs_frames()), imp)
        self.assertEqual(status, rq.NOT_MET)
        self.assertIn("strain mean 0.030 > DQS's 0.020", detail)

    def test_max_strain_slack_and_distance(self):
        frames = [frame(strain_max=0.3), frame(strain_max=0.45, distance=0.02),
                  frame()]
        status, detail = rq.target_shape(ok(dqs_frames()), ok(frames))
        self.assertEqual(status, rq.NOT_MET)
        self.assertIn("strain max 0.450 at frame 1 > DQS's 0.300 + 0.1",
                      detail)
        self.assertIn("distance from DQS 2.00% at frame 1 > 0.50%", detail)


class RestTarget(unittest.TestCase):
    def test_exact_rest_is_met(self):
        self.assertEqual(rq.target_rest(
            None, ok([frame()] * 3, rest_pose_error=1e-6))[0], rq.MET)

    def test_rest_error_and_nan(self):
        status, detail = rq.target_rest(
            None, ok([frame()] * 3, rest_pose_error=2e-5))
        self.assertEqual(status, rq.NOT_MET)
        self.assertIn("2.0e-05", detail)
        status, detail = rq.target_rest(None, failed())
        self.assertEqual(status, rq.NOT_MET)
        self.assertIn("not finite", detail)


def make_case_with_runs(name="CesiumMan.glb", clip=None, imp=None,
                        bulge=None):
    case = rq.make_case("/data/" + name, clip, clip is None)
    case["runs"] = {
        "lbs": ok(dqs_frames(), method="lbs"),
        "dqs": ok(dqs_frames(), method="dqs"),
        "auto": imp or ok([frame(new=n, crumpled=700 * n) for n in (0, 1, 2)]),
        "union": ok([frame(new=n) for n in (0, 1, 3)]),
        "blend": ok([frame(new=n) for n in (0, 9, 2)]),
        "bulge": bulge or failed("isk-skin: error: boom (exit 1)"),
    }
    case["clip_name"] = "walk"
    return case


class Cases(unittest.TestCase):
    def test_assets_and_builtins(self):
        cases = rq.make_cases(["/d/A.glb", "/d/B.fbx"], ["builtin:arm"])
        self.assertEqual(len(cases), 2 * 4 + 3)
        pictured = [c["slug"] for c in cases if c["picture"]]
        self.assertEqual(pictured, ["a-clip0", "b-clip0", "builtin-arm-bend120"])
        self.assertEqual(cases[1]["clip"], "bend:60")
        self.assertIsNone(cases[0]["clip"])
        quick = rq.make_cases(["/d/A.glb"], ["builtin:arm"], True)
        self.assertEqual([c["clip"] for c in quick],
                         [None, "bend:60", "bend:90", "bend:120"])
        only = rq.make_cases(["/d/A.glb"], ["builtin:cylinder"], only="cyl")
        self.assertEqual(len(only), 3)
        self.assertTrue(all(c["builtin"] for c in only))

    def test_list_assets_skips_readme_and_licence(self):
        with tempfile.TemporaryDirectory() as d:
            for name in ("README.md", "LICENSE", "a.glb", "b.X", "c.dae",
                         "d.txt", "e.gltf", "f.bin"):
                open(os.path.join(d, name), "w").close()
            os.mkdir(os.path.join(d, "sub.glb"))
            names = [os.path.basename(p) for p in rq.list_assets(d)]
            self.assertEqual(names, ["a.glb", "b.X", "c.dae", "e.gltf"])
        self.assertEqual(rq.list_assets("/nonexistent/folder"), [])

    def test_commands(self):
        # The run at the clip's own rate: isk-skin's frames, no frame files.
        self.assertEqual(
            rq.skin_command("isk", "/d/fox.glb", None, "implicit", None,
                            None, None, "/r.json"),
            ["isk", "/d/fox.glb", "--method", "implicit", "--overwrite",
             "--report", "/r.json"])
        self.assertEqual(
            rq.skin_command("isk", "builtin:arm", "bend:60", "implicit",
                            "blend", 12, "/o", "/r.json"),
            ["isk", "builtin:arm", "--method", "implicit", "--operator",
             "blend", "--clip", "bend:60", "--frames", "12", "--out", "/o",
             "--overwrite", "--report", "/r.json"])
        case = make_case_with_runs()
        for key in ("lbs", "dqs", "auto"):
            case["runs"][key]["dir"] = f"/w/{key}"
        command = rq.picture_command("pics", "/rest.obj", "/p.png",
                                     case["runs"], 2, "T")
        self.assertEqual(command[command.index("--focus") + 1], "2")
        self.assertEqual([command[i + 1] for i, c in enumerate(command)
                          if c == "--frame"],
                         ["/w/lbs/frame_0002.obj", "/w/dqs/frame_0002.obj",
                          "/w/auto/frame_0002.obj"])
        captions = [command[i + 1] for i, c in enumerate(command)
                    if c == "--caption"]
        self.assertEqual(captions[1], "DQS\nvolume 0.9000")
        self.assertTrue(captions[2].startswith("implicit auto\nvolume "))


class Render(unittest.TestCase):
    def results(self):
        good = make_case_with_runs()
        good["picture_file"], good["picture_frame"] = "cesiumman-clip0.png", 2
        # Jitter from the third frame: pops of 3%, 0.6%, 1.5%.
        good["rate_run"] = ok([frame(), frame(), frame(jitter=0.006),
                               frame(jitter=0.03), frame(jitter=0.015)])
        good["rate_run"]["report"]["quality"]["state_changes"] = {
            "mean": 12.25, "max": 31}
        bad = make_case_with_runs(
            "fox.glb", "bend:90",
            imp=ok([frame(new=9, volume=0.5, strain_mean=0.5)] * 3,
                   rest_pose_error=1e-3))
        bad["rate_run"] = failed()
        skipped = rq.make_case("/data/human-female.glb", "bend:90", False)
        skipped["runs"], skipped["skipped"] = {}, "the same as its first clip"
        return {"meta": {"date": "2026-01-01 00:00 UTC", "commit": "abc1234",
                         "frames": 3, "data": "../shared/data",
                         "builtins": ["builtin:arm"], "command": "cmd"},
                "cases": [good, bad, skipped]}

    def test_markdown(self):
        text = rq.render(self.results())
        self.assertIn("git commit `abc1234`", text)
        self.assertIn("Device: PoCL / cpu.", text)
        self.assertIn("3 frames per case", text)
        self.assertIn("per frame: things (test)", text)
        self.assertIn("implicit auto (default)", text)
        self.assertIn("![CesiumMan.glb, first clip 'walk': LBS, DQS and "
                      "implicit at frame 2](images/cesiumman-clip0.png)",
                      text)
        self.assertIn("failed: isk-skin: error: boom (exit 1)", text)
        self.assertIn('<a id="fox-bend90"></a>', text)
        self.assertIn("[fox.glb, procedural bend 90 degrees](#fox-bend90)",
                      text)
        self.assertIn("Not run: the same as its first clip.", text)
        self.assertIsNone(re.search(r"\b(nan|inf|None)\b", text))
        # The run at the clip's own rate: only the case that has one.
        rate = text.split("## Jitter at the clip's own rate", 1)[1]
        rate = rate.split("## Cases", 1)[0]
        self.assertIn("| [CesiumMan.glb, first clip 'walk'](#cesiumman-clip0)"
                      " | 5 | 3.00% | 3 | 2 | 3 | 0.85% | 12.2 | 31 |",
                      rate)
        self.assertIn("| state changes per frame mean | state changes max |",
                      rate)
        self.assertIn("| [fox.glb, procedural bend 90 degrees](#fox-bend90) "
                      "| failed: isk-skin: error: frame 3: vertex 7 is not "
                      "finite |  |  |  |  |  |  |  |", rate)
        self.assertNotIn("human-female", rate)
        # The summary rows: CesiumMan meets all 5, the fox none.
        summary_table = text.split("## Summary", 1)[1].split("## Jitter at", 1)[0]
        rows = {l.split(" | ")[0]: l for l in summary_table.splitlines()
                if l.startswith("| [")}
        cesium = rows["| [CesiumMan.glb, first clip 'walk'](#cesiumman-clip0)"]
        self.assertTrue(cesium.endswith("| 5 of 5 |"))
        # DQS's crumpled edges (none) and the default run's, 0 + 700 + 1400.
        self.assertIn("| 0 | 2,100 |", cesium)
        self.assertIn("crumpled edges sum", text)
        self.assertTrue(rows["| [fox.glb, procedural bend 90 degrees]"
                             "(#fox-bend90)"].endswith("| 0 of 5 |"))
        summary = text.split("## Summary of targets", 1)[1]
        self.assertIn("| volume kept | 1 met, 1 not met | 2 met, 0 not met "
                      "| 2 met, 0 not met | 0 met, 2 not met |", summary)
        self.assertIn("every target it can be judged on: 1 of 2", summary)
        # Table rows have as many cells as their header.
        for block in text.split("\n\n"):
            lines = [l for l in block.splitlines() if l.startswith("|")]
            if lines:
                widths = {l.replace("\\|", "").count("|") for l in lines}
                self.assertEqual(len(widths), 1, block)

    def test_parts_line(self):
        run = ok([frame(new=0)] * 3)
        self.assertEqual(rq.parts_line(run), "")  # no parts in the report
        run["report"]["quality"]["parts"] = [
            {"joint": "middle_01_r", "edges": 879, "edge_strain_mean": 0.2658,
             "dqs_edge_strain_mean": 0.0344, "dqs_distance_max": 0.0064},
            {"joint": "pelvis", "edges": 433, "edge_strain_mean": 0.1,
             "dqs_edge_strain_mean": 0.05, "dqs_distance_max": 0.001},
            {"joint": "head", "edges": 500, "edge_strain_mean": 0.01,
             "dqs_edge_strain_mean": 0.01, "dqs_distance_max": 0.0}]
        line = rq.parts_line(run)
        self.assertIn("middle_01_r 0.266 (DQS 0.034, up to 0.64% from DQS); "
                      "pelvis 0.100 (DQS 0.050, up to 0.10% from DQS).", line)
        self.assertNotIn("head", line)  # no excess over DQS's strain
        self.assertEqual(rq.parts_line(failed()), "")
        case = make_case_with_runs()
        case["runs"][rq.DEFAULT_IMPLICIT] = run
        self.assertIn(line, rq.case_section(case, "images", None))

    def test_pair_parts_line(self):
        run = ok([frame(new=0)] * 3)
        self.assertEqual(rq.pair_parts_line(run), "")  # no parts
        run["report"]["quality"]["parts"] = [
            {"joint": "Palm1.L", "edges": 90, "edge_strain_mean": 0.2,
             "dqs_edge_strain_mean": 0.1, "dqs_distance_max": 0.01,
             "new_pairs": 186, "dqs_new_pairs": 16},
            {"joint": "Index.L", "edges": 30, "edge_strain_mean": 0.2,
             "dqs_edge_strain_mean": 0.1, "dqs_distance_max": 0.01,
             "new_pairs": 1180, "dqs_new_pairs": 1000},
            {"joint": "Head", "edges": 3000, "edge_strain_mean": 0.01,
             "dqs_edge_strain_mean": 0.01, "dqs_distance_max": 0.0,
             "new_pairs": 40, "dqs_new_pairs": 400}]
        line = rq.pair_parts_line(run)
        # By excess over DQS's: Index.L 180 before Palm1.L 170.
        self.assertIn("Index.L 1,180 (DQS 1,000); Palm1.L 186 (DQS 16).",
                      line)
        self.assertNotIn("Head", line)  # fewer than DQS
        self.assertEqual(rq.pair_parts_line(failed()), "")
        case = make_case_with_runs()
        case["runs"][rq.DEFAULT_IMPLICIT] = run
        self.assertIn(line, rq.case_section(case, "images", None))

    def test_precision(self):
        self.assertEqual(rq.fmt_volume(0.912345), "0.9123")
        self.assertEqual(rq.fmt_strain(0.12345), "0.123")
        self.assertEqual(rq.pct(0.0012345), "0.12%")
        self.assertEqual(rq.sci(0.0), "0")
        self.assertEqual(rq.fmt_range((0.9, 1.0)), "0.9000 to 1.0000")


class Files(unittest.TestCase):
    def test_write_atomically_and_manifest(self):
        with tempfile.TemporaryDirectory() as d:
            out = os.path.join(d, "Q.md")
            rq.write_atomically(out, "one\n")
            rq.write_atomically(out, "two\n")
            self.assertEqual(read(out), "two\n")
            self.assertEqual(os.listdir(d), ["Q.md"])
            images = os.path.join(d, "images")
            os.makedirs(images)
            for name in ("old.png", "kept.png", "mine.png"):
                open(os.path.join(images, name), "w").close()
            with quiet():
                rq.update_manifest(images, ["old.png", "kept.png"])
                self.assertEqual(rq.update_manifest(images, ["kept.png"]),
                                 ["old.png"])
            self.assertEqual(sorted(os.listdir(images)),
                             sorted([rq.MANIFEST, "kept.png", "mine.png"]))


FAKE_SKIN = r'''#!/usr/bin/env python3
import json, os, sys
a = sys.argv[1:]
if a[0] == "builtin:list":
    print("builtin:cylinder"); sys.exit(0)
opt = lambda k, d=None: a[a.index(k) + 1] if k in a else d
method, op, clip = opt("--method"), opt("--operator"), opt("--clip")
n, out, rep = int(opt("--frames", 31)), opt("--out"), opt("--report")
rate = "--frames" not in a  # the run at the clip's own rate
if op == "bulge":
    sys.stderr.write("isk-skin: building fields\nisk-skin: error: boom\n")
    sys.exit(1)
assert rate == (out is None)
if out:
    os.makedirs(out, exist_ok=True)
for k in range(n if out else 0):
    open(os.path.join(out, "frame_%04d.obj" % k), "w").write("v 0 0 0\n")
if rep:
    bad = method == "implicit"
    frames = [dict(self_intersections=k, new_self_intersections=k,
                   volume_ratio=1 - 0.01 * k, edge_strain_mean=0.01,
                   edge_strain_max=0.1, contact_region_vertices=0,
                   dqs_distance_mean=0, dqs_distance_max=0.001 if bad else 0,
                   jitter_mean=None if k < 2 else 0.001,
                   jitter_max=None if k < 2 else 0.02 * (k == 5),
                   lost_vertices=0)
              for k in range(n)]
    q = dict(volume_ratio=dict(min=1 - 0.01 * (n - 1), max=1.0),
             rest_pose_error=0.0, edge_strain=dict(mean=0.01, max=0.1),
             self_intersections=dict(max=n - 1, total=n * (n - 1) // 2,
                                     at_rest=0, counted="pairs"),
             dqs_distance_max=0.001 if bad else 0, jitter_max=None,
             lost_vertices_max=0, worst_frame=n - 1, measures="m",
             frames=frames)
    if method == "implicit":
        q["state_changes"] = dict(mean=2.0, max=4)
    json.dump(dict(frames=n, vertices=1, triangles=0, method=method,
                   clip=clip or "bend", device="reference",
                   frame_ms=dict(median=1.0), quality=q), open(rep, "w"))
'''

FAKE_PICTURES = r'''#!/usr/bin/env python3
import sys
a = sys.argv[1:]
out = a[a.index("--out") + 1]
assert a[a.index("--focus") + 1] == "2" and a.count("--frame") == 3
open(out, "wb").write(b"\x89PNG fake")
'''


class WholeRun(unittest.TestCase):
    """One run of main() with stand-ins for the two programs."""

    def tool(self, folder, name, text):
        path = os.path.join(folder, name)
        with open(path, "w") as f:
            f.write(text)
        os.chmod(path, os.stat(path).st_mode | stat.S_IXUSR)
        return path

    def test_run(self):
        with tempfile.TemporaryDirectory() as d:
            skin = self.tool(d, "isk-skin", FAKE_SKIN)
            pictures = self.tool(d, "isk-frame-pictures", FAKE_PICTURES)
            data = os.path.join(d, "data")
            os.makedirs(data)
            for name in ("Clipless.glb", "README.md"):
                open(os.path.join(data, name), "w").close()
            out = os.path.join(d, "q", "QUALITY.md")
            images = os.path.join(d, "q", "images")
            os.makedirs(images)
            open(os.path.join(images, "gone.png"), "w").close()
            rq.write_atomically(os.path.join(images, rq.MANIFEST),
                                json.dumps({"files": ["gone.png"]}))
            with quiet():
                rq.main(["--skin", skin, "--pictures", pictures, "--data",
                         data, "--out", out, "--frames", "3", "--results",
                         os.path.join(d, "results.json")])
            text = read(out)
            self.assertIn("no clip of its own", text)
            self.assertIn("Not run: the same as its first clip", text)
            self.assertIn("failed: isk-skin: error: boom (exit 1)", text)
            # The first clip once more at 30 frames a second (31 made-up
            # frames, one pop of 2% at frame 5); not the bends.
            rate = text.split("## Jitter at the clip's own rate", 1)[1]
            rate = rate.split("## Cases", 1)[0]
            self.assertIn("| [Clipless.glb, no clip of its own: isk-skin's "
                          "90-degree bend](#clipless-clip0) | 31 | 2.00% | "
                          "5 | 1 | 1 | 0.10% | 2.0 | 4 |", rate)
            self.assertNotIn("bend120", rate)
            self.assertIn("](images/clipless-clip0.png)", text)
            self.assertIn("](images/builtin-cylinder-bend120.png)", text)
            self.assertEqual(sorted(os.listdir(images)),
                             sorted([rq.MANIFEST, "clipless-clip0.png",
                                     "builtin-cylinder-bend120.png"]))
            # Implicit's made-up frames equal DQS's pairs and volume: met;
            # the rest pose is exact; every case judged.
            summary = text.split("## Summary of targets", 1)[1]
            self.assertIn("| no new self-intersections beyond DQS | 6 met, "
                          "0 not met |", summary)
            self.assertIn("| rest pose exact, no NaN | 6 met, 0 not met | "
                          "6 met, 0 not met | 6 met, 0 not met | "
                          "0 met, 6 not met |", summary)
            self.assertEqual(sorted(os.listdir(os.path.join(d, "q"))),
                             ["QUALITY.md", "images"])
            again = os.path.join(d, "again.md")
            with quiet():
                rq.main(["--from-results", os.path.join(d, "results.json"),
                         "--out", again, "--images", images])
            self.assertIn("](q/images/clipless-clip0.png)", read(again))

    def test_missing_pictures_tool(self):
        with tempfile.TemporaryDirectory() as d:
            skin = self.tool(d, "isk-skin", FAKE_SKIN)
            out = os.path.join(d, "QUALITY.md")
            with quiet():
                rq.main(["--skin", skin, "--pictures",
                         os.path.join(d, "absent"), "--data",
                         os.path.join(d, "nodata"), "--out", out,
                         "--frames", "3"])
            text = read(out)
            self.assertIn("was not found when this file was written", text)
            self.assertNotIn("![", text)
            self.assertFalse(os.path.exists(os.path.join(d, "images")))


if __name__ == "__main__":
    unittest.main()
