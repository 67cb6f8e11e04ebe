#!/usr/bin/env python3
"""Measures the skinning quality of LBS, DQS and implicit skinning and writes
QUALITY.md at the repository root (with pictures under quality/images/)
from one run.

    python3 quality/run_quality.py                      # everything
    python3 quality/run_quality.py --only cylinder --out /tmp/q.md
    python3 quality/run_quality.py --skip-bends-on-assets   # quicker
    python3 quality/run_quality.py --from-results results.json  # no run

Every case (a shared asset with its first clip, and the procedural bends of
60, 90 and 120 degrees on the built-in rigs and on the assets) is skinned by
`isk-skin` with LBS, DQS and implicit skinning with its default composition
(auto: the union, with the blend at the limbs' joints) and with the union,
blend and bulge at every joint; the numbers
come from the JSON reports isk-skin writes (`quality` section), the targets
are evaluated here, and `isk-frame-pictures` draws the worst frame of the
implicit run beside LBS and DQS. Each asset's first clip is also skinned
once more by the implicit default at isk-skin's own 30 frames a second, for
the jitter between consecutive frames. A failed run is recorded with the
last line of its stderr and never stops the script. Progress goes to
stderr.

Python 3 standard library only.
"""
import argparse
import datetime
import json
import math
import os
import re
import shlex
import shutil
import subprocess
import sys
import tempfile
import time

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DEFAULT_OUT = os.path.join(REPO, "QUALITY.md")
DEFAULT_IMAGES = os.path.join(REPO, "quality", "images")
DEFAULT_SKIN = os.path.join("build", "samples", "isk-skin", "isk-skin")
DEFAULT_PICTURES = os.path.join("build", "samples", "frame-pictures",
                                "isk-frame-pictures")
ASSET_EXTENSIONS = (".glb", ".gltf", ".fbx", ".dae", ".x")
FALLBACK_BUILTINS = ("builtin:cylinder", "builtin:finger", "builtin:arm")
BENDS = (60, 90, 120)
# Deeper bends of the built-in rigs made for them (the leg at 150).
EXTRA_BENDS = {"builtin:leg": (150,)}
PICTURE_BEND_BUILTIN = 120
DEFAULT_FRAMES = 12
# The jitter measured at the animation's own rate (isk-skin's default
# frames, 30 a second): the frames in which some vertex's jitter passes
# these fractions of the diagonal are counted.
POP_LARGE = 0.01
POP_SMALL = 0.005
MANIFEST = ".written-by-run_quality.json"

# The runs of a case: key, isk-skin --method, --operator, label.
METHODS = (
    ("lbs", "lbs", None, "LBS"),
    ("dqs", "dqs", None, "DQS"),
    ("auto", "implicit", None, "implicit auto (default)"),
    ("union", "implicit", "union", "implicit union"),
    ("blend", "implicit", "blend", "implicit blend"),
    ("bulge", "implicit", "bulge", "implicit bulge"),
)
METHOD_LABEL = {key: label for key, _, _, label in METHODS}
IMPLICIT_KEYS = ("auto", "union", "blend", "bulge")
DEFAULT_IMPLICIT = "auto"  # `--method implicit` without --operator

# The targets' thresholds.
PAIRS_SUM_FLOOR = 100       # DQS's sum over the clip from which ...
PAIRS_SUM_FRACTION = 0.10   # ... implicit's sum must be at most this of it
VOLUME_FLOOR = 0.02         # |implicit/rest - 1| <= max(|DQS/rest - 1|, this)
STRAIN_MAX_SLACK = 0.1      # implicit max strain <= DQS's max + this
DQS_DISTANCE_MAX = 0.005    # of the diagonal
REST_POSE_ERROR_MAX = 1e-5  # of the diagonal
EPS = 1e-12                 # float noise in the comparisons

TARGETS = (
    ("pairs", "no new self-intersections beyond DQS"),
    ("volume", "volume kept"),
    ("covered", "covered volume kept"),
    ("shape", "shape of DQS kept"),
    ("rest", "rest pose exact, no NaN"),
)
TARGET_LABEL = dict(TARGETS)
TARGET_DEFINITIONS = {
    "pairs": "new self-intersecting pairs (not intersecting at rest) of "
             "implicit <= DQS's on every frame; and, where DQS's sum over "
             f"the clip is >= {PAIRS_SUM_FLOOR}, implicit's sum <= "
             f"{PAIRS_SUM_FRACTION:.0%} of DQS's.",
    "volume": "|implicit volume / rest volume - 1| <= max(|DQS volume / "
              f"rest volume - 1|, {VOLUME_FLOOR}) on every frame (n/a when "
              "the rest mesh encloses about no volume: open or flat "
              "meshes).",
    "covered": "the same with the covered volume (the volume enclosed once "
               "or more, where skin passing through skin counts once; the "
               "volume above counts it twice, so interpenetration raises "
               "it): |implicit covered / rest covered - 1| <= max(|DQS "
               f"covered / rest covered - 1|, {VOLUME_FLOOR}) on every frame.",
    "shape": "implicit's edge strain mean (mean over the frames) <= DQS's; "
             "implicit's largest edge strain <= DQS's largest + "
             f"{STRAIN_MAX_SLACK}; implicit's largest distance from the DQS "
             "frame of the same pose (vertices away from contacts) <= "
             f"{DQS_DISTANCE_MAX * 100:.1f}% of the rest bounding-box "
             "diagonal.",
    "rest": "implicit's rest-pose error (largest distance from the input "
            "at the bind pose, over the diagonal) <= "
            f"{REST_POSE_ERROR_MAX:.0e}; no NaN: isk-skin fails a frame with "
            "a non-finite position, so a failed run does not meet it.",
}
MET, NOT_MET, NA = "met", "not met", "n/a"


def log(message):
    print(message, file=sys.stderr, flush=True)


# --------------------------------------------------------------------------
# Cases.

def list_assets(data_dir):
    """The asset files of the data folder (sorted by name): the files with
    an asset extension; README, licence and other files are skipped."""
    if not data_dir or not os.path.isdir(data_dir):
        return []
    names = []
    for name in sorted(os.listdir(data_dir), key=str.lower):
        path = os.path.join(data_dir, name)
        if os.path.isfile(path) and name.lower().endswith(ASSET_EXTENSIONS):
            names.append(path)
    return names


def slugify(text):
    slug = re.sub(r"[^A-Za-z0-9]+", "-", text).strip("-").lower()
    return slug or "case"


def input_name(spec):
    """'builtin:arm' stays; '/x/CesiumMan.glb' -> 'CesiumMan.glb'."""
    return spec if spec.startswith("builtin:") else os.path.basename(spec)


def make_case(spec, clip, picture):
    """One case: `clip` None for the input's first clip (isk-skin's default:
    clip 0, or its 90-degree bend when the rig has no clip), else a --clip
    value such as 'bend:60'."""
    name = input_name(spec)
    stem = name if spec.startswith("builtin:") else os.path.splitext(name)[0]
    clip_part = "clip0" if clip is None else clip.replace(":", "")
    return {"input": spec, "name": name, "clip": clip,
            "clip_label": "first clip" if clip is None else clip,
            "slug": slugify(f"{stem}-{clip_part}"), "picture": picture,
            "builtin": spec.startswith("builtin:")}


def make_cases(assets, builtins, skip_bends_on_assets=False, only=None):
    """Assets with their first clip (pictured) and, unless skipped, their
    bends; the procedural rigs with their bends (pictured at 120 degrees).
    `only`: keep the cases whose input name, clip or slug holds it."""
    cases = []
    for spec in assets:
        cases.append(make_case(spec, None, True))
        if not skip_bends_on_assets:
            cases += [make_case(spec, f"bend:{d}", False) for d in BENDS]
    for spec in builtins:
        cases += [make_case(spec, f"bend:{d}", d == PICTURE_BEND_BUILTIN)
                  for d in BENDS + EXTRA_BENDS.get(spec, ())]
    if only:
        needle = only.lower()
        cases = [c for c in cases
                 if needle in c["name"].lower() or needle in c["slug"]
                 or needle in c["clip_label"].lower()
                 or needle in f"{c['name']} {c['clip_label']}".lower()]
    return cases


# --------------------------------------------------------------------------
# Running the programs.

def last_line(text):
    lines = [l.strip() for l in (text or "").splitlines() if l.strip()]
    return lines[-1] if lines else ""


def run_command(command, env, timeout):
    """(returncode, stderr); returncode None when it could not run or timed
    out (stderr then says why)."""
    try:
        done = subprocess.run(command, env=env, stdout=subprocess.DEVNULL,
                              stderr=subprocess.PIPE, text=True,
                              errors="replace", timeout=timeout)
        return done.returncode, done.stderr
    except subprocess.TimeoutExpired:
        return None, f"timed out after {timeout} s"
    except OSError as error:
        return None, f"could not run {command[0]}: {error}"


def skin_command(exe, spec, clip, method, operator, frames, out_dir,
                 report=None, device=None):
    """frames None: isk-skin's default (30 a second); out_dir None: no
    frame files."""
    command = [exe, spec, "--method", method]
    if operator:
        command += ["--operator", operator]
    if clip is not None:
        command += ["--clip", clip]
    if frames is not None:
        command += ["--frames", str(frames)]
    if out_dir is not None:
        command += ["--out", out_dir]
    command += ["--overwrite"]
    if report:
        command += ["--report", report]
    if device:
        command += ["--device", device]
    return command


def run_skin(exe, spec, clip, method, operator, frames, out_dir, report,
             env, timeout, device=None):
    """One isk-skin run: {ok, report, error, seconds, dir}."""
    if out_dir is not None:
        os.makedirs(out_dir, exist_ok=True)
    os.makedirs(os.path.dirname(report), exist_ok=True)
    if os.path.exists(report):
        os.remove(report)
    command = skin_command(exe, spec, clip, method, operator, frames,
                           out_dir, report, device)
    started = time.monotonic()
    code, stderr = run_command(command, env, timeout)
    seconds = time.monotonic() - started
    result = {"ok": False, "report": None, "error": None,
              "seconds": round(seconds, 1), "dir": out_dir}
    if code != 0:
        why = last_line(stderr) or f"exit status {code}"
        result["error"] = why if code is None else f"{why} (exit {code})"
        return result
    try:
        with open(report) as f:
            result["report"] = json.load(f)
        result["ok"] = True
    except (OSError, ValueError) as error:
        result["error"] = f"no readable report: {error}"
    return result


def builtin_rigs(exe, env):
    """`isk-skin builtin:list`'s names, else the known ones."""
    try:
        done = subprocess.run([exe, "builtin:list"], env=env,
                              capture_output=True, text=True, timeout=120)
        names = [l.strip() for l in done.stdout.splitlines()
                 if l.strip().startswith("builtin:")]
        if done.returncode == 0 and names:
            return names
    except (OSError, subprocess.TimeoutExpired):
        pass
    log("run_quality.py: warning: `isk-skin builtin:list` gave no names; "
        "using " + ", ".join(FALLBACK_BUILTINS))
    return list(FALLBACK_BUILTINS)


def frame_path(run, index):
    return os.path.join(run["dir"], f"frame_{index:04d}.obj")


def frame_quality(run, index):
    """quality.frames[index] of a run, or {}."""
    if not run or not run.get("ok"):
        return {}
    frames = quality_of(run).get("frames") or []
    return frames[index] if 0 <= index < len(frames) else {}


def picture_caption(key, run, index):
    q = frame_quality(run, index)
    # isk-frame-pictures adds a line with the panel's new pairs.
    volume = q.get("volume_ratio")
    return "\n".join([METHOD_LABEL[key].replace(" (default)", ""),
                      f"volume {fmt_volume(volume)}" if volume is not None
                      else "volume n/a"])


def picture_command(exe, rest_obj, out, runs, index, title):
    command = [exe, "--rest", rest_obj, "--out", out, "--focus", "2",
               "--overwrite", "--title", title]
    for key in ("lbs", "dqs", DEFAULT_IMPLICIT):
        command += ["--frame", frame_path(runs[key], index),
                    "--caption", picture_caption(key, runs[key], index)]
    return command


# --------------------------------------------------------------------------
# Reading the reports.

def quality_of(run):
    if not run or not run.get("ok") or not run.get("report"):
        return {}
    return run["report"].get("quality") or {}


def quality_frames(run):
    return quality_of(run).get("frames") or []


def new_pairs(run):
    """The new self-intersecting pairs of each frame (list, maybe empty)."""
    return [f.get("new_self_intersections", 0) for f in quality_frames(run)]


def pairs_stat(run, reduce, summary_key):
    """`reduce` of the per-frame new pairs, else the report's summary."""
    if quality_frames(run):
        return reduce(new_pairs(run))
    si = quality_of(run).get("self_intersections")
    return si.get(summary_key) if si else None


def pairs_sum(run):
    return pairs_stat(run, sum, "total")


def pairs_max(run):
    return pairs_stat(run, max, "max")


def crumpled_sum(run):
    """Crumpled edges summed over the frames (None where not reported)."""
    c = quality_of(run).get("crumpled_edges")
    return c.get("total") if c else None


def volume_range(run, field="volume_ratio"):
    v = quality_of(run).get(field)
    return (v.get("min"), v.get("max")) if v else None


def strain(run):
    s = quality_of(run).get("edge_strain")
    return (s.get("mean"), s.get("max")) if s else None


def device_text(report):
    device = (report or {}).get("device")
    if device is None:
        return None
    if isinstance(device, str):
        return "CPU reference" if device == "reference" else device
    text = device.get("name") or "?"
    if device.get("platform"):
        text = f"{device['platform']} / {text}"
    return text


# --------------------------------------------------------------------------
# The targets. Each takes the DQS run and an implicit run ({ok, report,
# error}) and gives (status, detail).

def _failed(run):
    return not run or not run.get("ok") or not run.get("report")


def _run_error(run):
    return (run or {}).get("error") or "no report"


def _common(dqs, implicit):
    """(status, detail) when the comparison cannot be made, else None."""
    if _failed(implicit):
        return NOT_MET, f"the run failed: {_run_error(implicit)}"
    if _failed(dqs):
        return NA, f"the DQS run failed: {_run_error(dqs)}"
    return None


def _frame_count_note(a, b):
    return ("" if len(a) == len(b) else
            f" (compared over {min(len(a), len(b))} frames: DQS has "
            f"{len(a)}, implicit {len(b)})")


def target_pairs(dqs, implicit):
    common = _common(dqs, implicit)
    if common:
        return common
    d, i = quality_frames(dqs), quality_frames(implicit)
    if not d or not i:
        return NA, "no per-frame measures in the reports"
    dn = [f.get("new_self_intersections", 0) for f in d]
    im = [f.get("new_self_intersections", 0) for f in i]
    n = min(len(dn), len(im))
    note = _frame_count_note(dn, im)
    worse = [k for k in range(n) if im[k] > dn[k]]
    problems = []
    if worse:
        k = max(worse, key=lambda k: (im[k] - dn[k], -k))
        problems.append(
            f"{len(worse)} frame{'s' if len(worse) != 1 else ''} with more "
            f"new pairs than DQS, worst frame {k}: {im[k]} vs DQS {dn[k]}")
    d_sum, i_sum = sum(dn[:n]), sum(im[:n])
    if d_sum >= PAIRS_SUM_FLOOR and i_sum > PAIRS_SUM_FRACTION * d_sum + EPS:
        problems.append(f"sum {i_sum} > {PAIRS_SUM_FRACTION:.0%} of DQS's "
                        f"{d_sum} ({PAIRS_SUM_FRACTION * d_sum:.1f})")
    if problems:
        return NOT_MET, "; ".join(problems) + note
    detail = f"sum {i_sum} vs DQS {d_sum}"
    if d_sum >= PAIRS_SUM_FLOOR:
        detail += f" (<= {PAIRS_SUM_FRACTION:.0%})"
    return MET, detail + note


def target_volume(dqs, implicit, field="volume_ratio"):
    common = _common(dqs, implicit)
    if common:
        return common
    d, i = quality_frames(dqs), quality_frames(implicit)
    if not d or not i:
        if volume_range(implicit, field) is None:
            return NA, "no enclosed volume (open or flat mesh)"
        return NA, "no per-frame measures in the reports"
    n = min(len(d), len(i))
    worst, worst_excess, offending, compared = None, 0.0, 0, 0
    for k in range(n):
        dv, iv = d[k].get(field), i[k].get(field)
        if dv is None or iv is None:
            continue
        compared += 1
        bound = max(abs(dv - 1), VOLUME_FLOOR)
        excess = abs(iv - 1) - bound
        if excess > EPS:
            offending += 1
            if worst is None or excess > worst_excess:
                worst, worst_excess = (k, iv, dv, bound), excess
    if not compared:
        return NA, "no enclosed volume (open or flat mesh)"
    note = _frame_count_note(d, i)
    if worst:
        k, iv, dv, bound = worst
        return NOT_MET, (
            f"{offending} frame{'s' if offending != 1 else ''}, worst frame "
            f"{k}: |{iv:.4f} - 1| = {abs(iv - 1):.4f} > max(|{dv:.4f} - 1|, "
            f"{VOLUME_FLOOR}) = {bound:.4f}{note}")
    ir = volume_range(implicit, field)
    detail = (f"{ir[0]:.4f} to {ir[1]:.4f}" if ir and ir[0] is not None
              else f"{compared} frames")
    return MET, detail + note


def _argmax_frame(run, field):
    frames = quality_frames(run)
    best = None
    for k, f in enumerate(frames):
        v = f.get(field)
        if v is not None and (best is None or v > best[1]):
            best = (k, v)
    return best


def target_shape(dqs, implicit):
    common = _common(dqs, implicit)
    if common:
        return common
    ds, is_ = strain(dqs), strain(implicit)
    distance = quality_of(implicit).get("dqs_distance_max")
    if ds is None or is_ is None or None in ds or None in is_:
        return NA, "no edge strain in the reports"
    problems, good = [], []
    if is_[0] > ds[0] + EPS:
        problems.append(f"strain mean {is_[0]:.3f} > DQS's {ds[0]:.3f}")
    else:
        good.append(f"strain mean {is_[0]:.3f} (DQS {ds[0]:.3f})")
    if is_[1] > ds[1] + STRAIN_MAX_SLACK + EPS:
        at = _argmax_frame(implicit, "edge_strain_max")
        where = f" at frame {at[0]}" if at else ""
        problems.append(f"strain max {is_[1]:.3f}{where} > DQS's "
                        f"{ds[1]:.3f} + {STRAIN_MAX_SLACK}")
    else:
        good.append(f"max {is_[1]:.3f} (DQS {ds[1]:.3f})")
    if distance is None:
        good.append("no distance from DQS")
    elif distance > DQS_DISTANCE_MAX + EPS:
        at = _argmax_frame(implicit, "dqs_distance_max")
        where = f" at frame {at[0]}" if at else ""
        problems.append(f"distance from DQS {pct(distance)}{where} > "
                        f"{pct(DQS_DISTANCE_MAX)}")
    else:
        good.append(f"distance from DQS {pct(distance)}")
    if problems:
        return NOT_MET, "; ".join(problems)
    return MET, ", ".join(good)


def target_rest(dqs, implicit):
    del dqs  # the rest pose is implicit's own
    if _failed(implicit):
        return NOT_MET, f"the run failed: {_run_error(implicit)}"
    error = quality_of(implicit).get("rest_pose_error")
    if error is None:
        return NA, "no rest-pose error in the report"
    if not math.isfinite(error) or error > REST_POSE_ERROR_MAX:
        return NOT_MET, (f"rest-pose error {sci(error)} > "
                         f"{REST_POSE_ERROR_MAX:.0e} of the diagonal")
    return MET, f"rest-pose error {sci(error)}; every frame finite"


def target_covered(dqs, implicit):
    return target_volume(dqs, implicit, "covered_volume_ratio")


TARGET_FUNCTIONS = {"pairs": target_pairs, "volume": target_volume,
                    "covered": target_covered,
                    "shape": target_shape, "rest": target_rest}


def evaluate_targets(dqs, implicit):
    """{target key: (status, detail)} of one implicit run against DQS."""
    return {key: TARGET_FUNCTIONS[key](dqs, implicit) for key, _ in TARGETS}


def evaluate_case(runs):
    """{implicit key: {target key: (status, detail)}} of a case's runs."""
    return {key: evaluate_targets(runs.get("dqs"), runs.get(key))
            for key in IMPLICIT_KEYS}


def met_count(evaluation):
    """(met, evaluated) of one implicit run's targets (n/a not counted)."""
    statuses = [s for s, _ in evaluation.values()]
    return (statuses.count(MET), len([s for s in statuses if s != NA]))


def target_summary(cases, key=DEFAULT_IMPLICIT):
    """{target: {met, not met, n/a}} over the cases."""
    out = {t: {MET: 0, NOT_MET: 0, NA: 0} for t, _ in TARGETS}
    for case in cases:
        if case.get("skipped"):
            continue
        evaluation = evaluate_case(case["runs"])[key]
        for t, (status, _) in evaluation.items():
            out[t][status] += 1
    return out


# --------------------------------------------------------------------------
# Formatting.

def fmt_volume(v):
    return "n/a" if v is None else f"{v:.4f}"


def fmt_strain(v):
    return "n/a" if v is None else f"{v:.3f}"


def pct(v):
    """A fraction of the diagonal as a percentage."""
    return "n/a" if v is None else f"{v * 100:.2f}%"


def sci(v):
    if v is None:
        return "n/a"
    return "0" if v == 0 else f"{v:.1e}"


def fmt_count(v):
    return "n/a" if v is None else f"{int(v):,}"


def fmt_ms(v):
    if v is None:
        return "n/a"
    return f"{v:.3f}" if v < 10 else (f"{v:.2f}" if v < 100 else f"{v:.1f}")


def fmt_range(r):
    if r is None or r[0] is None:
        return "n/a"
    return f"{r[0]:.4f} to {r[1]:.4f}"


def fmt_strains(s):
    if s is None:
        return "n/a"
    return f"{fmt_strain(s[0])} / {fmt_strain(s[1])}"


def cell(text):
    """Table-safe text: no pipes, no newlines."""
    return str(text).replace("|", "\\|").replace("\n", " ")


def table(header, rows, align=None):
    if not rows:
        return []
    align = align or ["l"] + ["r"] * (len(header) - 1)
    lines = ["| " + " | ".join(header) + " |",
             "|" + "|".join("---" if a == "l" else "---:" for a in align)
             + "|"]
    lines += ["| " + " | ".join(cell(c) for c in row) + " |" for row in rows]
    return lines + [""]


def verdict(status, detail=None):
    shown = "**not met**" if status == NOT_MET else status
    return f"{shown}: {detail}" if detail else shown


def case_title(case):
    clip = case.get("clip_name")
    if case["clip"] is None:
        if case.get("no_clip"):
            label = "no clip of its own: isk-skin's 90-degree bend"
        else:
            label = "first clip" + (f" '{clip}'" if clip else "")
    else:
        label = f"procedural {case['clip'].replace(':', ' ')} degrees"
    return f"{case['name']}, {label}"


def failed_cell(run):
    return f"failed: {_run_error(run)}"


def method_row(key, run):
    label = METHOD_LABEL[key]
    if _failed(run):
        return [label, failed_cell(run)] + [""] * 14
    report = run["report"]
    q = quality_of(run)
    si = q.get("self_intersections") or {}
    contact = q.get("contact_vertices")
    return [label, fmt_count(report.get("frames")),
            fmt_ms((report.get("frame_ms") or {}).get("median")),
            fmt_count(pairs_sum(run)), fmt_count(pairs_max(run)),
            fmt_count(si.get("at_rest")), fmt_range(volume_range(run)),
            fmt_range(volume_range(run, "covered_volume_ratio")),
            fmt_strain((strain(run) or (None, None))[0]),
            fmt_strain((strain(run) or (None, None))[1]),
            fmt_count(crumpled_sum(run)),
            pct(q.get("dqs_distance_max")), pct(q.get("jitter_max")),
            fmt_count(q.get("lost_vertices_max")),
            "" if contact is None else f"{contact:g}",
            fmt_count(q.get("worst_frame"))]


METHOD_HEADER = ["method", "frames", "ms/frame", "new pairs sum",
                 "new pairs max", "pairs at rest", "volume",
                 "covered volume", "strain mean",
                 "strain max", "crumpled edges sum", "distance from DQS max",
                 "jitter max", "lost max", "contact vertices", "worst frame"]

SUMMARY_HEADER = ["case", "vertices", "DQS new pairs", "implicit new pairs",
                  "DQS volume", "implicit volume", "DQS covered volume",
                  "implicit covered volume", "DQS strain mean / max",
                  "implicit strain mean / max",
                  "DQS crumpled edges", "implicit crumpled edges",
                  "implicit distance from DQS max", "implicit jitter max",
                  "implicit lost max", "targets met (default)"]


def summary_row(case):
    runs = case["runs"]
    dqs, imp = runs.get("dqs"), runs.get(DEFAULT_IMPLICIT)
    link = f"[{case_title(case)}](#{case['slug']})"
    if case.get("skipped"):
        return [link] + [""] * 14 + [case["skipped"]]
    vertices = next((r["report"].get("vertices") for r in runs.values()
                     if not _failed(r)), None)

    def of(run, text):
        return "failed" if _failed(run) else text

    met, evaluated = met_count(evaluate_case(runs)[DEFAULT_IMPLICIT])
    qi = quality_of(imp)
    return [link, fmt_count(vertices),
            of(dqs, fmt_count(pairs_sum(dqs))),
            of(imp, fmt_count(pairs_sum(imp))),
            of(dqs, fmt_range(volume_range(dqs))),
            of(imp, fmt_range(volume_range(imp))),
            of(dqs, fmt_range(volume_range(dqs, "covered_volume_ratio"))),
            of(imp, fmt_range(volume_range(imp, "covered_volume_ratio"))),
            of(dqs, fmt_strains(strain(dqs))),
            of(imp, fmt_strains(strain(imp))),
            of(dqs, fmt_count(crumpled_sum(dqs))),
            of(imp, fmt_count(crumpled_sum(imp))),
            of(imp, pct(qi.get("dqs_distance_max"))),
            of(imp, pct(qi.get("jitter_max"))),
            of(imp, fmt_count(qi.get("lost_vertices_max"))),
            f"{met} of {evaluated}" + (f" ({len(TARGETS) - evaluated} n/a)"
                                       if evaluated < len(TARGETS) else "")]


def header_section(meta, cases):
    devices = []
    for case in cases:
        for run in case["runs"].values():
            text = None if _failed(run) else device_text(run["report"])
            if text and text not in devices:
                devices.append(text)
    lines = ["# Skinning quality", "",
             "Written by `quality/run_quality.py` from one run of `isk-skin` "
             "(and `isk-frame-pictures` for the pictures). Every figure comes "
             "from the JSON reports of that run; the text and the targets' "
             "thresholds are fixed in the script.", "",
             "## How to reproduce", "",
             "```sh",
             "./run.sh build && python3 quality/run_quality.py",
             "```", "",
             "This file was written by:", "", "```sh",
             meta.get("command", "python3 quality/run_quality.py"), "```",
             ""]
    seconds = meta.get("seconds")
    took = ("" if seconds is None else
            f", {seconds / 60:.1f} minutes" if seconds >= 120 else
            f", {seconds:.0f} seconds")
    lines.append(f"- Run of {meta.get('date', '?')}, git commit "
                 f"`{meta.get('commit', '?')}`{took}.")
    lines.append("- Device: " + ("; ".join(devices) if devices else
                                 "none (no run succeeded)") + ".")
    lines.append(f"- {meta.get('frames', '?')} frames per case, uniformly "
                 "over the clip from its first key to its last.")
    run_cases = [c for c in cases if not c.get("skipped")]
    lines.append(f"- {len(run_cases)} cases, each skinned with LBS, DQS and "
                 "implicit skinning with its default composition (`--method "
                 "implicit`, that is `--operator auto`: the union, with the "
                 "gradient-based blend at the joints of mirrored limbs) and "
                 "with the union, blend and bulge at every joint "
                 "(`--operator union|blend|bulge`). The default run is the "
                 "one the targets are judged on (the others are reported "
                 "beside it).")
    lines.append("- Cases: every asset of the data folder "
                 f"(`{meta.get('data', '?')}`) with its first clip "
                 "(isk-skin's default clip: clip 0, or a 90-degree bend of every joint "
                 "when the asset has none)"
                 + ("" if meta.get("skip_bends_on_assets") else
                    ", and the procedural bend of every joint from 0 to 60, "
                    "90 and 120 degrees (`--clip bend:DEGREES`) on the "
                    "assets")
                 + " and on the built-in rigs ("
                 + ", ".join(f"`{b}`" for b in meta.get("builtins", []))
                 + ")"
                 + "".join(f"; `{b}` also at "
                           + ", ".join(f"{d}" for d in EXTRA_BENDS[b])
                           + " degrees"
                           for b in meta.get("builtins", [])
                           if b in EXTRA_BENDS)
                 + "."
                 + (f" Only the cases matching `{meta['only']}`."
                    if meta.get("only") else ""))
    lines.append("")
    return lines


def measures_section(cases):
    measures = counted = None
    for case in cases:
        for run in case["runs"].values():
            q = quality_of(run)
            measures = measures or q.get("measures")
            counted = counted or (q.get("self_intersections") or {}).get(
                "counted")
    lines = ["## Measures and targets", ""]
    if measures:
        lines.append(f"isk-skin's measures, {measures}.")
    else:
        lines.append("isk-skin's measures: no report of this run has them.")
    if counted:
        lines.append(f"Self-intersecting pairs are {counted}.")
    lines += ["", "In the tables: 'new pairs sum' is the sum over the frames "
              "of the new self-intersecting pairs, 'new pairs max' the "
              "largest frame's; 'volume' the range of the volume ratio over "
              "the frames (the signed enclosed volume: where skin passes "
              "through skin the overlap counts twice), 'covered volume' that "
              "of the covered volume ratio (the volume enclosed once or "
              "more: the overlap counts once); 'strain mean' the mean over the frames of each "
              "frame's mean edge strain, 'strain max' the largest; "
              "'crumpled edges' the sum over the frames of the edges "
              "between two triangles whose bending angle changed from rest "
              "by more than 60 degrees (crumples and spikes: reported, not "
              "a target); distances "
              "and jitter are percentages of the rest bounding-box diagonal; "
              "'lost' the tracking's lost vertices (largest frame); "
              "'contact vertices' the median over the frames of the "
              "vertices stopped at a contact; 'worst frame' the frame with "
              "the most new pairs (on a tie, the one whose volume is "
              "furthest from the rest volume).", "",
              "The targets, judged on each case's implicit default (auto) "
              "run against the DQS run of the same case:", ""]
    for key, label in TARGETS:
        lines.append(f"- **{label}**: {TARGET_DEFINITIONS[key]}")
    lines += ["", "Each target is 'met', 'not met' (with the offending "
              "frame and numbers) or 'n/a' (cannot be measured, e.g. an "
              "open mesh's volume, or a failed DQS run).", ""]
    return lines


def summary_section(cases):
    lines = ["## Summary", ""]
    if not cases:
        return lines + ["No case was run.", ""]
    lines += table(SUMMARY_HEADER, [summary_row(c) for c in cases])
    return lines


RATE_HEADER = ["case", "frames", "implicit jitter max", "at frame",
               f"frames with jitter past {POP_LARGE:.0%}",
               f"frames with jitter past {POP_SMALL:.1%}",
               "implicit jitter mean", "state changes per frame mean",
               "state changes max"]


def rate_row(case):
    """The row of a case's run at the clip's own rate, or None without
    one."""
    run = case.get("rate_run")
    if run is None:
        return None
    link = f"[{case_title(case)}](#{case['slug']})"
    if _failed(run):
        return [link, failed_cell(run)] + [""] * (len(RATE_HEADER) - 2)
    frames = quality_frames(run)
    largest = [f.get("jitter_max") for f in frames]
    means = [f.get("jitter_mean") for f in frames
             if f.get("jitter_mean") is not None]
    measured = [(j, k) for k, j in enumerate(largest) if j is not None]
    changes = quality_of(run).get("state_changes")
    change_cells = (["n/a", "n/a"] if not changes else
                    [f"{changes['mean']:.1f}", fmt_count(changes["max"])])
    if not measured:
        return ([link, fmt_count(len(frames)), "n/a", "n/a", "n/a", "n/a",
                 "n/a"] + change_cells)
    worst, at = max(measured, key=lambda m: (m[0], -m[1]))
    return [link, fmt_count(len(frames)), pct(worst), str(at),
            fmt_count(sum(1 for j, _ in measured if j > POP_LARGE)),
            fmt_count(sum(1 for j, _ in measured if j > POP_SMALL)),
            pct(sum(means) / len(means) if means else None)] + change_cells


def rate_section(cases, frames):
    """The first clips once more with the implicit default at 30 frames a
    second: the jitter between consecutive frames, which the cases' frames,
    far apart in time, cannot tell from a contact that comes and goes
    between two of them."""
    rows = [r for r in (rate_row(c) for c in cases) if r is not None]
    if not rows:
        return []
    lines = ["## Jitter at the clip's own rate", "",
             "Each asset's first clip once more, skinned by implicit "
             "skinning with its default composition at isk-skin's default "
             "of 30 frames a second (`isk-skin INPUT --method implicit`, "
             f"no `--frames`). The cases below sample {frames} frames over "
             "a whole clip, so their jitter also counts a contact that "
             "comes and goes between two samples; here consecutive frames "
             "are 1/30 s apart. Jitter is the second difference of each "
             "vertex's offset from its DQS position over three consecutive "
             "frames (DQS's own is 0 by construction): how abruptly the "
             "frames depart from DQS's motion. A pop, a vertex that leaves "
             "DQS's motion for one frame and comes back, shows as a large "
             "value; so does an offset that changes fast in a fast motion. "
             "'implicit jitter max' is the largest over the vertices and "
             "frames (a percentage of the rest bounding-box diagonal) and "
             "'at frame' the last of its three frames; the next two columns "
             "count the frames in which some vertex's jitter passes "
             f"{POP_LARGE:.0%} and {POP_SMALL:.1%} of the diagonal; "
             "'implicit jitter mean' is the mean over the frames of each "
             "frame's mean over the vertices. The last two columns count "
             "the vertices whose tracking state (converged, contact, "
             "crease, lost...) differs from the frame before's, the mean "
             "over the frames and the largest: contacts and creases that "
             "come and go switch the smoothing around them on and off, "
             "which is where the frames pop. Reported, not a target.", ""]
    return lines + table(RATE_HEADER, rows)


def parts_line(run, count=3):
    """The parts (bones' parts) whose mean edge strain exceeds DQS's most in
    an implicit run's report (quality.parts, largest excess first), or ''."""
    shown = []
    for p in (quality_of(run).get("parts") or [])[:count]:
        if not p["edge_strain_mean"] > p["dqs_edge_strain_mean"]:
            break
        shown.append(f"{p['joint']} {fmt_strain(p['edge_strain_mean'])} "
                     f"(DQS {fmt_strain(p['dqs_edge_strain_mean'])}, up to "
                     f"{pct(p['dqs_distance_max'])} from DQS)")
    if not shown:
        return ""
    return ("Parts whose edge strain exceeds DQS's most (implicit default, "
            "mean over the frames; `isk-skin --report`'s quality.parts): "
            + "; ".join(shown) + ".")


def pair_parts_line(run, count=3):
    """The parts whose new self-intersecting pairs (summed over the frames)
    exceed DQS's most in an implicit run's report (quality.parts), or ''."""
    parts = [p for p in (quality_of(run).get("parts") or [])
             if "new_pairs" in p and p["new_pairs"] > p["dqs_new_pairs"]]
    parts.sort(key=lambda p: p["dqs_new_pairs"] - p["new_pairs"])
    shown = [f"{p['joint']} {p['new_pairs']:,} (DQS {p['dqs_new_pairs']:,})"
             for p in parts[:count]]
    if not shown:
        return ""
    return ("Parts whose new pairs exceed DQS's most (implicit default, "
            "summed over the frames, a pair counted in each part it touches; "
            "`isk-skin --report`'s quality.parts): " + "; ".join(shown) + ".")


def case_section(case, images_rel, pictures_note):
    lines = [f'<a id="{case["slug"]}"></a>', "",
             f"### {case_title(case)}", ""]
    if case.get("skipped"):
        return lines + [f"Not run: {case['skipped']}.", ""]
    runs = case["runs"]
    shown = case["input"] if case["builtin"] else case["name"]
    lines.append(f"`isk-skin {shown}"
                 + ("" if case["clip"] is None else f" --clip {case['clip']}")
                 + "`" + (f"; {case['note']}" if case.get("note") else "")
                 + ".")
    lines.append("")
    lines += table(METHOD_HEADER,
                   [method_row(key, runs.get(key)) for key, *_ in METHODS])
    evaluation = evaluate_case(runs)
    rows = []
    for t, label in TARGETS:
        rows.append([label] + [verdict(*evaluation[k][t])
                               for k in IMPLICIT_KEYS])
    lines += table(["target"] + [METHOD_LABEL[k] for k in IMPLICIT_KEYS],
                   rows, ["l"] * (len(IMPLICIT_KEYS) + 1))
    for parts in (parts_line(runs.get(DEFAULT_IMPLICIT)),
                  pair_parts_line(runs.get(DEFAULT_IMPLICIT))):
        if parts:
            lines += [parts, ""]
    if case["picture"]:
        picture = case.get("picture_file")
        if picture:
            lines += [f"![{case_title(case)}: LBS, DQS and implicit at frame "
                      f"{case.get('picture_frame')}]"
                      f"({images_rel}/{picture})", "",
                      f"*Frame {case.get('picture_frame')} (the implicit "
                      "default run's worst), LBS, DQS and implicit side by "
                      "side: the whole mesh above, a close-up of the "
                      "implicit frame's worst place below; triangles of new "
                      "intersecting pairs are orange.*", ""]
        else:
            why = case.get("picture_note") or pictures_note or "not drawn"
            lines += [f"No picture: {why}.", ""]
    return lines


def targets_summary_section(cases):
    run_cases = [c for c in cases if not c.get("skipped")]
    lines = ["## Summary of targets", ""]
    if not run_cases:
        return lines + ["No case was run.", ""]
    lines.append(f"How many of the {len(run_cases)} cases meet each target "
                 "(the default is the one judged; the union, blend and "
                 "bulge at every joint for comparison):")
    lines.append("")
    rows = []
    summaries = {k: target_summary(run_cases, k) for k in IMPLICIT_KEYS}
    for t, label in TARGETS:
        row = [label]
        for k in IMPLICIT_KEYS:
            s = summaries[k][t]
            text = f"{s[MET]} met, {s[NOT_MET]} not met"
            if s[NA]:
                text += f", {s[NA]} n/a"
            row.append(text)
        rows.append(row)
    lines += table(["target"] + [METHOD_LABEL[k] for k in IMPLICIT_KEYS],
                   rows, ["l"] * (len(IMPLICIT_KEYS) + 1))
    all_met = sum(
        1 for c in run_cases
        if all(s != NOT_MET for s, _ in
               evaluate_case(c["runs"])[DEFAULT_IMPLICIT].values()))
    lines.append(f"Cases whose implicit default run meets every target it "
                 f"can be judged on: {all_met} of {len(run_cases)}.")
    lines.append("")
    return lines


def render(results, images_rel="images"):
    """The markdown of a run's results: {meta, cases}; each case as
    make_case gives plus `runs` {method key: {ok, report, error, ...}} and,
    where drawn, `picture_file`, `picture_frame` (or `picture_note`)."""
    meta, cases = results.get("meta", {}), results.get("cases", [])
    lines = header_section(meta, cases)
    lines += measures_section(cases)
    lines += summary_section(cases)
    lines += rate_section(cases, meta.get("frames", "?"))
    lines += ["## Cases", ""]
    for case in cases:
        lines += case_section(case, images_rel, meta.get("pictures_note"))
    lines += targets_summary_section(cases)
    return "\n".join(lines).rstrip() + "\n"


# --------------------------------------------------------------------------
# Files.

def write_atomically(path, text):
    folder = os.path.dirname(os.path.abspath(path))
    os.makedirs(folder, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix="." + os.path.basename(path) + ".",
                               suffix=".tmp", dir=folder)
    try:
        with os.fdopen(fd, "w") as f:
            f.write(text)
        os.chmod(tmp, 0o644)  # mkstemp's 0600 would be committed as is
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.remove(tmp)
        raise


def install_file(source, target):
    """Copies `source` to `target` through a temporary name beside it."""
    folder = os.path.dirname(os.path.abspath(target))
    os.makedirs(folder, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=".", suffix=".tmp", dir=folder)
    os.close(fd)
    try:
        shutil.copyfile(source, tmp)
        os.chmod(tmp, 0o644)
        os.replace(tmp, target)
    except BaseException:
        if os.path.exists(tmp):
            os.remove(tmp)
        raise


def read_manifest(images_dir):
    try:
        with open(os.path.join(images_dir, MANIFEST)) as f:
            return [n for n in json.load(f).get("files", [])
                    if isinstance(n, str) and os.path.basename(n) == n]
    except (OSError, ValueError, AttributeError):
        return []


def update_manifest(images_dir, written):
    """Removes the pictures an earlier run of this script wrote that this
    run did not (files the script did not write are never touched), then
    records this run's."""
    stale = sorted(set(read_manifest(images_dir)) - set(written))
    for name in stale:
        path = os.path.join(images_dir, name)
        if os.path.isfile(path):
            os.remove(path)
            log(f"removed stale picture {path}")
    if written or stale or os.path.exists(os.path.join(images_dir, MANIFEST)):
        write_atomically(os.path.join(images_dir, MANIFEST),
                         json.dumps({"files": sorted(written)}, indent=1)
                         + "\n")
    return stale


def git_commit():
    try:
        done = subprocess.run(["git", "rev-parse", "--short", "HEAD"],
                              cwd=REPO, capture_output=True, text=True,
                              timeout=30)
        return done.stdout.strip() or "unknown"
    except (OSError, subprocess.TimeoutExpired):
        return "unknown"


def resolve(path):
    """A program or folder path: relative ones are from the repository."""
    return path if os.path.isabs(path) else os.path.join(REPO, path)


def shown_path(path):
    path = os.path.abspath(path)
    inside = os.path.commonpath([path, REPO]) == REPO
    return os.path.relpath(path, REPO) if inside else path


def shown_data(path):
    """The data folder as shown: relative to the repository when it is
    inside it or beside it (../shared/data), else absolute."""
    relative = os.path.relpath(os.path.abspath(path), REPO)
    parts = relative.split(os.sep)
    return relative if parts.count("..") <= 1 else os.path.abspath(path)


# --------------------------------------------------------------------------
# The run.

def run_case(case, index, total, args, env, work):
    """Skins one case with every method; draws its picture."""
    case_dir = os.path.join(work, case["slug"])
    runs = {}
    for key, method, operator, label in METHODS:
        log(f"[case {index}/{total}] {case['name']} {case['clip_label']} "
            f"{label}")
        runs[key] = run_skin(args.skin, case["input"], case["clip"], method,
                             operator, args.frames,
                             os.path.join(case_dir, key),
                             os.path.join(case_dir, f"{key}.json"), env,
                             args.timeout, args.device)
        if not runs[key]["ok"]:
            log(f"    failed: {runs[key]['error']}")
    case["runs"] = runs
    if case["clip"] is None:
        log(f"[case {index}/{total}] {case['name']} {case['clip_label']} "
            "implicit at 30 frames a second")
        case["rate_run"] = run_skin(
            args.skin, case["input"], None, "implicit", None, None, None,
            os.path.join(case_dir, "rate.json"), env, args.timeout,
            args.device)
        if not case["rate_run"]["ok"]:
            log(f"    failed: {case['rate_run']['error']}")
    for run in runs.values():
        if not _failed(run):
            case["clip_name"] = run["report"].get("clip")
            break
    if case["clip"] is None and case.get("clip_name") == "bend":
        case["no_clip"] = True
    return case_dir


def draw_picture(case, args, env, work, images_dir, rest_cache):
    runs = case["runs"]
    if any(_failed(runs.get(k)) for k in ("lbs", "dqs", DEFAULT_IMPLICIT)):
        case["picture_note"] = ("a run it needs (LBS, DQS, implicit "
                                "default) failed")
        return None
    frame = quality_of(runs[DEFAULT_IMPLICIT]).get("worst_frame")
    if frame is None or frame < 0:
        case["picture_note"] = "the implicit report has no worst frame"
        return None
    missing = [k for k in ("lbs", "dqs", DEFAULT_IMPLICIT)
               if not os.path.isfile(frame_path(runs[k], frame))]
    if missing:
        case["picture_note"] = f"frame {frame} of {', '.join(missing)} missing"
        return None
    rest = rest_cache.get(case["input"])
    if rest is None:
        rest_dir = os.path.join(work, "rest", slugify(case["name"]))
        os.makedirs(rest_dir, exist_ok=True)
        command = skin_command(args.skin, case["input"], "rest", "dqs", None,
                               1, rest_dir, device=args.device)
        code, stderr = run_command(command, env, args.timeout)
        rest = os.path.join(rest_dir, "frame_0000.obj")
        if code != 0 or not os.path.isfile(rest):
            rest = {"error": last_line(stderr) or f"exit {code}"}
        rest_cache[case["input"]] = rest
    if isinstance(rest, dict):
        case["picture_note"] = f"the rest pose failed: {rest['error']}"
        return None
    name = f"{case['slug']}.png"
    log(f"    picture of frame {frame}: {name}")
    drawn = os.path.join(work, "pictures", name)
    os.makedirs(os.path.dirname(drawn), exist_ok=True)
    title = f"{case_title(case)}: frame {frame}"
    command = picture_command(args.pictures, rest, drawn, runs, frame, title)
    code, stderr = run_command(command, env, args.timeout)
    if code != 0 or not os.path.isfile(drawn):
        case["picture_note"] = ("isk-frame-pictures failed: "
                                + (last_line(stderr) or f"exit {code}"))
        log(f"    picture: {case['picture_note']}")
        return None
    install_file(drawn, os.path.join(images_dir, name))
    case["picture_file"], case["picture_frame"] = name, frame
    return name


def script_command(argv):
    return shlex.join(["python3", "quality/run_quality.py"] + argv)


def collect(args, argv):
    """Runs every case; returns the results {meta, cases} and the pictures
    written."""
    env = dict(os.environ)
    if not env.get("POCL_CACHE_DIR"):
        env["POCL_CACHE_DIR"] = os.path.join(REPO, ".pocl-cache")
    os.makedirs(env["POCL_CACHE_DIR"], exist_ok=True)
    if not (os.path.isfile(args.skin) and os.access(args.skin, os.X_OK)):
        sys.exit(f"run_quality.py: {args.skin} not found: build first "
                 "(./run.sh build) or pass --skin")
    pictures_note = None
    if not (os.path.isfile(args.pictures) and os.access(args.pictures,
                                                        os.X_OK)):
        pictures_note = (f"{shown_path(args.pictures)} was not found when "
                         "this file was written (build it, or pass "
                         "--pictures), so there are no pictures")
        log(f"run_quality.py: warning: {pictures_note}")
    elif args.no_pictures:
        pictures_note = "run with --no-pictures"

    assets = list_assets(args.data)
    if not assets:
        log(f"run_quality.py: warning: no asset in {args.data}")
    builtins = builtin_rigs(args.skin, env)
    cases = make_cases(assets, builtins, args.skip_bends_on_assets, args.only)
    meta = {"date": datetime.datetime.now(datetime.timezone.utc)
            .strftime("%Y-%m-%d %H:%M UTC"),
            "commit": git_commit(), "frames": args.frames,
            "data": shown_data(args.data), "builtins": builtins,
            "only": args.only,
            "skip_bends_on_assets": args.skip_bends_on_assets,
            "command": script_command(argv),
            "pictures_note": pictures_note}
    started = time.monotonic()
    work = args.keep_frames or tempfile.mkdtemp(prefix="isk-quality-")
    os.makedirs(work, exist_ok=True)
    images_dir = args.images
    written = []
    rest_cache = {}
    no_clip_inputs = set()
    try:
        for i, case in enumerate(cases, 1):
            if (case["clip"] == "bend:90"
                    and case["input"] in no_clip_inputs):
                case["skipped"] = ("the same as its first clip: the asset "
                                   "has no clip, so isk-skin bends it 90 "
                                   "degrees")
                case["runs"] = {}
                log(f"[case {i}/{len(cases)}] {case['name']} "
                    f"{case['clip_label']}: skipped ({case['skipped']})")
                continue
            case_dir = run_case(case, i, len(cases), args, env, work)
            if case.get("no_clip"):
                no_clip_inputs.add(case["input"])
            if case["picture"] and not pictures_note:
                name = draw_picture(case, args, env, work, images_dir,
                                    rest_cache)
                if name:
                    written.append(name)
            if not args.keep_frames:
                shutil.rmtree(case_dir, ignore_errors=True)
    finally:
        if not args.keep_frames:
            shutil.rmtree(work, ignore_errors=True)
    meta["seconds"] = round(time.monotonic() - started)
    # What the markdown needs of a run: no frame folders that are gone.
    for case in cases:
        for run in list(case.get("runs", {}).values()) + (
                [case["rate_run"]] if case.get("rate_run") else []):
            if not args.keep_frames:
                run.pop("dir", None)
    return {"meta": meta, "cases": cases}, written


def parse_args(argv):
    default_data = os.environ.get("ISK_DATA_DIR") or os.path.join(
        REPO, "..", "shared", "data")
    parser = argparse.ArgumentParser(
        description="Skin every shared asset and procedural rig with LBS, "
                    "DQS and implicit skinning and write QUALITY.md.")
    parser.add_argument("--skin", default=DEFAULT_SKIN,
                        help="isk-skin (default: " + DEFAULT_SKIN + ", from "
                             "the repository root)")
    parser.add_argument("--pictures", default=DEFAULT_PICTURES,
                        help="isk-frame-pictures (default: "
                             + DEFAULT_PICTURES + "); without it, no "
                             "pictures")
    parser.add_argument("--data", default=default_data,
                        help="the asset folder (default: $ISK_DATA_DIR, else "
                             "../shared/data from the repository root)")
    parser.add_argument("--out", default=DEFAULT_OUT,
                        help="the markdown written (default: QUALITY.md at "
                             "the repository root)")
    parser.add_argument("--images",
                        help="the pictures' folder (default: quality/images "
                             "for the default --out, else images/ beside "
                             "--out)")
    parser.add_argument("--frames", type=int, default=DEFAULT_FRAMES,
                        help=f"frames per case (default {DEFAULT_FRAMES})")
    parser.add_argument("--only", help="run only the cases whose input name "
                        "or clip holds this")
    parser.add_argument("--skip-bends-on-assets", action="store_true",
                        help="assets with their first clip only")
    parser.add_argument("--device", help="--device passed to isk-skin "
                        "(default: its own, auto)")
    parser.add_argument("--timeout", type=int, default=1800,
                        help="seconds one isk-skin run may take (default "
                             "1800)")
    parser.add_argument("--keep-frames", metavar="DIR",
                        help="keep the frames and reports in DIR (default: a "
                             "temporary folder, removed at the end)")
    parser.add_argument("--no-pictures", action="store_true",
                        help="draw no picture")
    parser.add_argument("--results", metavar="FILE",
                        help="also save the run's results (reports and "
                             "verdict inputs) as JSON")
    parser.add_argument("--from-results", metavar="FILE",
                        help="write the markdown from a --results file, run "
                             "nothing")
    parser.add_argument("--self-test", action="store_true",
                        help="run quality/test_run_quality.py and exit")
    args = parser.parse_args(argv)
    if args.frames < 1:
        parser.error("--frames must be at least 1")
    args.skin = os.path.abspath(resolve(args.skin))
    args.pictures = os.path.abspath(resolve(args.pictures))
    args.data = os.path.abspath(resolve(args.data))
    args.out = os.path.abspath(args.out)
    if not args.images:
        args.images = (DEFAULT_IMAGES if args.out == os.path.abspath(
            DEFAULT_OUT) else os.path.join(os.path.dirname(args.out),
                                           "images"))
    args.images = os.path.abspath(args.images)
    if args.keep_frames:
        args.keep_frames = os.path.abspath(args.keep_frames)
    return args


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    args = parse_args(argv)
    if args.self_test:
        here = os.path.dirname(os.path.abspath(__file__))
        return subprocess.call([sys.executable, "-B",
                                os.path.join(here, "test_run_quality.py")])
    written = None
    if args.from_results:
        with open(args.from_results) as f:
            results = json.load(f)
    else:
        results, written = collect(args, argv)
        if args.results:
            write_atomically(args.results,
                             json.dumps(results, indent=1) + "\n")
    images_rel = os.path.relpath(args.images, os.path.dirname(args.out))
    text = render(results, images_rel.replace(os.sep, "/"))
    write_atomically(args.out, text)
    if written is not None and not results["meta"].get("pictures_note"):
        update_manifest(args.images, written)
    log(f"== wrote {args.out}"
        + (f" and {len(written)} pictures in {args.images}" if written
           else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
