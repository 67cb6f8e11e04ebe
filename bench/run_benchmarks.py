#!/usr/bin/env python3
"""Runs the benchmark suite (build/bench/isk_bench) and writes bench/BENCHMARKS.md.

    python3 bench/run_benchmarks.py                  # everything
    python3 bench/run_benchmarks.py --filter 'CesiumMan$|^OperatorTable/' \\
        --min-time 0.1 --out /tmp/partial.md           # a short partial run
    python3 bench/run_benchmarks.py --from-json build/bench/benchmarks.json
    python3 bench/run_benchmarks.py --only-python --out /tmp/python.md

The JSON of the run is saved next to the executable (benchmarks.json), then
BENCHMARKS.md is written from it, entirely: every number in it comes from the
JSON (or, for the paper's Table 1, from the paper), the text around the
numbers is static. A partial JSON (a --filter run) gives the sections it has
data for; the others say "not run". Progress goes to stderr.

After isk_bench (unless --skip-python), bench/python_frames.py (the isk
Python module's frames, with the build's Python and its python/ folder) and
bench/blender_frames.py (Blender's frames with the add-on, from the build's
isk_blender.zip) run; their JSON goes into the run's JSON under the key
"isk_python_blender" ({"python": ..., "blender": ...}, each the script's
JSON or {"skipped": why} or {"failed": why}), so --from-json renders them
too. --only-python runs those two alone and writes their JSON
(python-blender.json beside the executable) and markdown (python-blender.md
beside that JSON).

Python 3 standard library only.
"""
import argparse
import glob
import datetime
import json
import math
import os
import platform
import re
import shlex
import shutil
import subprocess
import sys
import tempfile

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# Google Benchmark's own name parts, appended after ours.
GB_SUFFIX = re.compile(
    r"^(min_time|min_warmup_time|iterations|repeats|real_time|manual_time|"
    r"process_time)(:.*)?$")

# Figures of the paper's Table 1 (Vaillant et al. 2013, GTX 680): model,
# vertices, implicit skinning fps, DQS fps (a string: ">800" is a bound).
PAPER_TABLE_1 = [
    ("Dana", 4164, 95, ">800"),
    ("Carl", 6866, 68, ">800"),
    ("hand", 31750, 15, "95"),
    ("Juna", 32056, 15, "340"),
    ("Armadillo", 172974, 3, "87"),
]

# What "the ~40k-vertex model" and "the ~170k-vertex model" of the targets
# mean: every model whose vertex count lies in these ranges.
RANGE_40K = (30000, 50000)
RANGE_170K = (120000, 220000)
# The targets' thresholds (the performance issue).
TARGET_FPS_40K = 15.0
TARGET_FPS_HUMAN = 60.0
TARGET_RATIO_170K = 5.0
TARGET_SPEEDUP = 1.6
# The speed-up target is checked on every model of at least this many
# vertices (human-addon subdivided once lands below 30,000).
SPEEDUP_MIN_VERTICES = 25000
TARGET_GPU_FPS_170K = 300.0

STAGES = ("upload", "skinning", "projection", "relaxation", "smoothing",
          "volume", "strain_limit", "normals", "readback")


def stage_cell(run, stage, frame_ms):
    """A stage's ms and share of the frame; n/a where the run did not time it
    (runs recorded before the stage had a counter)."""
    value = run.get(stage + "_ms")
    if value is None:
        return "n/a"
    return f"{ms(value)} ({100 * value / frame_ms:.0f}%)"


def log(message):
    print(message, file=sys.stderr, flush=True)


# --------------------------------------------------------------------------
# Running the suite.

def run_suite(args):
    bench = os.path.abspath(args.bench)
    if not os.path.isfile(bench):
        sys.exit(f"run_benchmarks.py: {bench} not found: build first "
                 "(./run.sh build) or pass --bench")
    json_path = os.path.abspath(
        args.json or os.path.join(os.path.dirname(bench), "benchmarks.json"))
    command = [bench, f"--benchmark_out={json_path}",
               "--benchmark_out_format=json"]
    if args.filter:
        command.append(f"--benchmark_filter={args.filter}")
    if args.min_time is not None:
        command.append(f"--benchmark_min_time={args.min_time}")
    command += args.bench_args
    env = dict(os.environ)
    if not env.get("POCL_CACHE_DIR"):
        env["POCL_CACHE_DIR"] = os.path.join(REPO, ".pocl-cache")
    os.makedirs(env["POCL_CACHE_DIR"], exist_ok=True)

    listing = subprocess.run(
        [bench, "--benchmark_list_tests=true"]
        + ([f"--benchmark_filter={args.filter}"] if args.filter else []),
        env=env, capture_output=True, text=True)
    total = len([l for l in listing.stdout.splitlines() if l.strip()])
    log(f"== {total} benchmarks: {shlex.join(command)}")
    started = datetime.datetime.now(datetime.timezone.utc)
    process = subprocess.Popen(command, env=env, stdout=subprocess.PIPE,
                               text=True, bufsize=1)
    done = 0
    for line in process.stdout:
        line = line.rstrip("\n")
        name = line.split(" ", 1)[0]
        if "/" in name and not name.startswith("-"):
            done += 1
            elapsed = (datetime.datetime.now(datetime.timezone.utc)
                       - started).total_seconds()
            log(f"[{done}/{total} {elapsed:.0f} s] {line}")
        else:
            log(line)
    if process.wait() != 0:
        sys.exit(f"run_benchmarks.py: isk_bench exited with "
                 f"{process.returncode}")
    elapsed = (datetime.datetime.now(datetime.timezone.utc)
               - started).total_seconds()
    log(f"== done in {elapsed:.0f} s; JSON: {json_path}")
    return json_path, command, elapsed


def build_dir(args):
    """The build folder the isk_bench executable lies in (<build>/bench)."""
    return os.path.dirname(os.path.dirname(os.path.abspath(args.bench)))


def run_figures_script(name, command, env, json_path, summary_marker):
    """Runs bench/python_frames.py or bench/blender_frames.py; returns its
    JSON, or {"skipped": why} (exit code 77) or {"failed": why}: a failure
    here must not lose the isk_bench run before it."""
    log(f"== {name}: {shlex.join(command)}")
    started = datetime.datetime.now(datetime.timezone.utc)
    process = subprocess.run(command, env=env, capture_output=True,
                             text=True)
    seconds = (datetime.datetime.now(datetime.timezone.utc)
               - started).total_seconds()
    lines = (process.stdout + process.stderr).splitlines()
    own = [l for l in lines if l.startswith(name)]
    if process.returncode == 77:
        why = next((l.split("SKIP: ", 1)[1] for l in own if "SKIP: " in l),
                   "skipped")
        log(f"== {name}: skipped: {why}")
        return {"skipped": why}
    if process.returncode != 0 or not os.path.isfile(json_path):
        log("\n".join(lines[-20:]))
        log(f"== {name}: failed (exit {process.returncode})")
        # The last line of its error output says why, in most cases.
        last = next((l.strip() for l in reversed(process.stderr.splitlines())
                     if l.strip()), "")
        last = last if len(last) <= 200 else last[:200] + " ..."
        return {"failed": f"exit code {process.returncode}"
                + (f" ({last})" if last else "")}
    # The script's summary, without Blender's own output around it.
    start = next((i for i, l in enumerate(lines) if summary_marker in l),
                 len(lines))
    log("\n".join(l for l in lines[start:] if not l.startswith(name)))
    with open(json_path) as f:
        report = json.load(f)
    report["command"] = command_text_of(command, json_path, env)
    report["wall_seconds"] = seconds
    return report


def command_text_of(command, json_path, env):
    """A script's command as the markdown shows it: paths inside the
    repository relative, with the PYTHONPATH it was given."""
    shown = []
    if env.get("PYTHONPATH"):
        shown.append("PYTHONPATH=" + os.pathsep.join(
            shown_path(p) for p in env["PYTHONPATH"].split(os.pathsep)))
    for c in command:
        if c == json_path:
            shown.append("OUT.json")
        elif os.path.isabs(c):
            shown.append(shown_path(c))
        else:
            shown.append(c)
    return shlex.join(shown)


def module_python(args):
    """The interpreter the isk module was built for: --python, else the
    build's CMake cache says, else this one."""
    if args.python:
        return args.python
    cache = os.path.join(build_dir(args), "CMakeCache.txt")
    if os.path.isfile(cache):
        with open(cache) as f:
            for line in f:
                m = re.match(r"Python3_EXECUTABLE:FILEPATH=(.+)$", line)
                if m and os.path.isfile(m.group(1).strip()):
                    return m.group(1).strip()
    return sys.executable


def run_python_and_blender(args):
    """The Python module's and Blender's frames (bench/python_frames.py,
    bench/blender_frames.py), each skipped with a reason when its module or
    Blender is missing: {"python": ..., "blender": ...}."""
    build = build_dir(args)
    module = os.path.abspath(args.python_module
                             or os.path.join(build, "python"))
    addon_zip = os.path.abspath(args.blender_zip
                                or os.path.join(build, "isk_blender.zip"))
    env = dict(os.environ)
    if not env.get("POCL_CACHE_DIR"):
        env["POCL_CACHE_DIR"] = os.path.join(REPO, ".pocl-cache")
    # The field caches of the two scripts: builds are not what they time.
    env.setdefault("ISK_CACHE_DIR", os.path.join(build, "isk-cache"))
    out = {}
    with tempfile.TemporaryDirectory(prefix="isk-bench-") as folder:
        if not os.path.isdir(os.path.join(module, "isk")):
            out["python"] = {"skipped": f"no isk module in "
                             f"{shown_path(module)} (build the target "
                             "_isk and isk_python_package, or pass "
                             "--python-module)"}
        else:
            json_path = os.path.join(folder, "python.json")
            python_env = dict(env)
            python_env["PYTHONPATH"] = os.pathsep.join(
                [module] + ([env["PYTHONPATH"]] if env.get("PYTHONPATH")
                            else []))
            out["python"] = run_figures_script(
                "python_frames.py",
                [module_python(args), os.path.join(REPO, "bench",
                                              "python_frames.py"),
                 "--json", json_path], python_env, json_path,
                "Python module frames")
        blender = shutil.which(args.blender)
        if not blender:
            out["blender"] = {"skipped": f"no `{args.blender}` executable "
                              "on the PATH"}
        elif not os.path.isfile(addon_zip):
            out["blender"] = {"skipped": f"no add-on zip "
                              f"{shown_path(addon_zip)} (build the target "
                              "isk_blender_zip, or pass --blender-zip)"}
        else:
            json_path = os.path.join(folder, "blender.json")
            # Blender's embedded Python takes the standard library of the
            # first python3.x on the PATH: not this script's interpreter
            # (a pyenv one, say), but the one Blender was built with.
            blender_env = dict(env)
            here = os.path.dirname(os.path.abspath(sys.executable))
            blender_env["PATH"] = os.pathsep.join(
                p for p in env.get("PATH", "").split(os.pathsep)
                if p and os.path.abspath(p) != here)
            out["blender"] = run_figures_script(
                "blender_frames.py",
                [args.blender, "-b", "--factory-startup",
                 "--python-exit-code", "1", "--python",
                 os.path.join(REPO, "bench", "blender_frames.py"), "--",
                 "--json", json_path, "--zip", addon_zip], blender_env,
                json_path,
                "frame changes on")
    return out


# --------------------------------------------------------------------------
# Reading the JSON.

def to_ms(run):
    scale = {"ns": 1e-6, "us": 1e-3, "ms": 1.0, "s": 1e3}
    return run["real_time"] * scale.get(run.get("time_unit", "ns"), 1e-6)


class Results:
    """The runs of one JSON, by their name parts (Google Benchmark's
    suffixes removed); mean aggregates win over single repetitions."""

    def __init__(self, data):
        self.context = data.get("context", {})
        self.runs = {}
        self.failed = []
        have_mean = set()
        for b in data.get("benchmarks", []):
            # run_name: the name without an aggregate's _mean/_stddev.
            parts = b.get("run_name", b["name"]).split("/")
            while parts and GB_SUFFIX.match(parts[-1]):
                parts.pop()
            key = tuple(parts)
            if b.get("run_type") == "aggregate":
                if b.get("aggregate_name") != "mean":
                    continue
                have_mean.add(key)
                self.runs[key] = b
                continue
            if b.get("error_occurred"):
                self.failed.append((b["name"], b.get("error_message", "")))
                continue
            if key not in have_mean:
                self.runs[key] = b
        self.devices = {}
        for k, v in self.context.items():
            m = re.fullmatch(r"isk_device_(\d+)", k)
            if m:
                d = int(m.group(1))
                self.devices[d] = {
                    "name": v,
                    "type": self.context.get(f"isk_device_{d}_type", "other")}
        # Devices seen only through names and labels (a JSON without the
        # context keys).
        for key, run in self.runs.items():
            if self.context.get("isk_device_0"):
                break
            for part in key:
                m = re.fullmatch(r"(opencl|opencl-buffer|opencl-image|dqs|paired|"
                                 r"implicit|cold|warm|in-process|all|"
                                 r"no-neighbourhoods|no-neighbourhood-cells|"
                                 r"no-march-order|no-occupied-cells|"
                                 r"no-value-bounds|no-lane-tests|"
                                 r"no-active-vertices|no-pair-bounds|"
                                 r"x\d+):(\d+)",
                                 part)
                if m and int(m.group(2)) not in self.devices:
                    self.devices[int(m.group(2))] = {
                        "name": run.get("label", "?"), "type": "other"}

    def family(self, name):
        return {k: v for k, v in self.runs.items() if k and k[0] == name}

    def get(self, *key):
        return self.runs.get(tuple(key))

    def device_name(self, d):
        return self.devices.get(d, {}).get("name", f"device {d}")

    def cpu_devices(self):
        return [d for d, v in sorted(self.devices.items())
                if v["type"] == "cpu"]

    def gpu_devices(self):
        return [d for d, v in sorted(self.devices.items())
                if v["type"] == "gpu"]


def split_device(part):
    """'opencl:0' -> ('opencl', 0); 'reference' -> ('reference', None)."""
    m = re.fullmatch(r"(.+):(\d+)", part)
    return (m.group(1), int(m.group(2))) if m else (part, None)


def ordered(items, order):
    """Keys sorted by their position in `order` (unknown ones last)."""
    index = {k: i for i, k in enumerate(order)}
    return sorted(items, key=lambda k: (index.get(k, len(order)), str(k)))


# --------------------------------------------------------------------------
# Formatting.

def ms(value, digits=None):
    if value is None:
        return "n/a"
    if digits is None:
        digits = 3 if value < 10 else (2 if value < 100 else 1)
    return f"{value:.{digits}f}"


def fps_of(ms_value):
    return 1000.0 / ms_value if ms_value else None


def fps(value):
    if value is None:
        return "n/a"
    return f"{value:.0f}" if value >= 100 else f"{value:.1f}"


def ratio(value, digits=2):
    return "n/a" if value is None else f"{value:.{digits}f}x"


def count(value):
    return "n/a" if value is None else f"{int(round(value)):,}"


def table(header, rows, align=None):
    """A markdown table; `align` one of 'l'/'r' per column (default: the
    first column left, the others right)."""
    if not rows:
        return []
    align = align or ["l"] + ["r"] * (len(header) - 1)
    lines = ["| " + " | ".join(header) + " |",
             "|" + "|".join("---" if a == "l" else "---:" for a in align)
             + "|"]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return lines + [""]


def model_order(results):
    """Model names in the order the suite registers them (first seen)."""
    seen = []
    for key in results.runs:
        for family, index in (("Implicit", 1), ("Frame", 2), ("FieldEval", 2),
                              ("FieldBuild", 1)):
            if key[0] == family and len(key) > index:
                if key[index] not in seen:
                    seen.append(key[index])
    return seen


# --------------------------------------------------------------------------
# Sections. Each returns markdown lines.

def header_section(results, command_text, elapsed):
    ctx = results.context
    lines = ["# Benchmarks", "",
             "Written by `bench/run_benchmarks.py` from one run of "
             "`bench/isk_bench` (Google Benchmark). Every figure below comes "
             "from that run's JSON, except the paper's own figures in the "
             "Table 1 comparison; the text is fixed in the script.", "",
             "## How to reproduce", "",
             "```sh",
             "./run.sh benchmarks     # build, run the whole suite, write "
             "BENCHMARKS.md",
             "```", "",
             "This file was written by the command below (with the "
             "benchmark command it ran):", "", "```sh", command_text, "```",
             ""]
    lines += [f"- Run of {ctx.get('date', '?')} on host "
              f"`{ctx.get('host_name', '?')}`: {ctx.get('num_cpus', '?')} "
              f"CPUs at {ctx.get('mhz_per_cpu', '?')} MHz, load average "
              f"before the run "
              + ", ".join(f"{x:.2f}" for x in ctx.get("load_avg", []))
              + "."]
    if elapsed is not None:
        lines.append(f"- The run took {elapsed / 60:.1f} minutes."
                     if elapsed >= 120 else
                     f"- The run took {elapsed:.0f} seconds.")
    if results.devices:
        for d, v in sorted(results.devices.items()):
            lines.append(f"- OpenCL device {d} ({v['type']}): {v['name']}.")
    else:
        lines.append("- No OpenCL device in this run.")
    if not results.gpu_devices():
        lines.append("- No GPU device in this run: the GPU figures come "
                     "from the recorded runs at the end of this file, if "
                     "any, else they read 'no GPU run'.")
    lines.append("- 'CPU reference' is the library's single-thread C++ "
                 "implementation of the same frame.")
    lines.append("- Google Benchmark reports its own library as a "
                 f"`{ctx.get('library_build_type', '?')}` build; this "
                 "project is built Release.")
    lines.append("")
    return lines


def implicit_models(results):
    """{model: {backend_key: run}} of the Implicit family."""
    out = {}
    for key, run in results.family("Implicit").items():
        if len(key) >= 3:
            out.setdefault(key[1], {})[key[2]] = run
    return out


def implicit_over_dqs(runs, d, backend="opencl"):
    """implicit / DQS on device d of one model's (or scaling point's) runs:
    from the frames timed side by side ('paired:<d>') where the run has
    them, else the separate implicit and DQS benchmarks' times (older JSON,
    recorded runs); None without either."""
    paired = runs.get(f"paired:{d}")
    if paired and paired.get("implicit_over_dqs"):
        return paired["implicit_over_dqs"]
    cl, dqs = runs.get(f"{backend}:{d}"), runs.get(f"dqs:{d}")
    if cl and dqs:
        return to_ms(cl) / to_ms(dqs)
    return None


def ratio_cell(runs, d, backend="opencl"):
    """implicit / DQS as a table cell: with the paired frames' times when
    the ratio comes from them."""
    r = implicit_over_dqs(runs, d, backend)
    paired = runs.get(f"paired:{d}")
    if r is None or not (paired and paired.get("implicit_over_dqs")):
        return ratio(r, 1)
    return (f"{ratio(r, 1)} (paired: {ms(paired.get('implicit_ms'))} / "
            f"{ms(paired.get('dqs_ms'))} ms)")


def gpu_target_rows(results, where=""):
    """Target rows a run's GPU devices give: the ~170k-vertex model's fps
    and its implicit / DQS ratio. `where` is appended to the model cell."""
    rows = []
    for model, runs in implicit_models(results).items():
        for d in results.gpu_devices():
            cl, dqs = runs.get(f"opencl:{d}"), runs.get(f"dqs:{d}")
            if not cl:
                continue
            v = int(cl["vertices"])
            if not RANGE_170K[0] <= v <= RANGE_170K[1]:
                continue
            cell = f"{model} ({v:,} v), {results.device_name(d)}{where}"
            f = fps_of(to_ms(cl))
            rows.append([f"implicit, ~170k vertices, GPU: >= "
                         f"{TARGET_GPU_FPS_170K:.0f} fps", cell,
                         f"{fps(f)} fps",
                         "met" if f >= TARGET_GPU_FPS_170K else "**not met**"])
            r = implicit_over_dqs(runs, d)
            if r is not None and where:
                rows.append([f"implicit / DQS, ~170k vertices, same device: "
                             f"<= {TARGET_RATIO_170K:.0f}x", cell,
                             ratio(r, 1),
                             "met" if r <= TARGET_RATIO_170K
                             else "**not met**"])
    return rows


def targets_section(results, recorded=()):
    lines = ["## Targets", "",
             "The performance issue's targets, measured in this run "
             "(reported, never asserted by tests). 'The ~40k-vertex model' is "
             f"every model of {RANGE_40K[0]:,} to {RANGE_40K[1]:,} vertices, "
             f"'the ~170k-vertex model' every model of {RANGE_170K[0]:,} to "
             f"{RANGE_170K[1]:,}; PoCL targets are checked on every CPU "
             "OpenCL device, the speed-up on every model of at least "
             f"{SPEEDUP_MIN_VERTICES:,} vertices.", ""]
    models = implicit_models(results)
    rows = []

    def verdict(ok):
        return "met" if ok else "**not met**"

    cpu = results.cpu_devices()
    for model, runs in models.items():
        for d in cpu:
            cl = runs.get(f"opencl:{d}")
            if not cl:
                continue
            v = int(cl["vertices"])
            f = fps_of(to_ms(cl))
            dev = results.device_name(d)
            if RANGE_40K[0] <= v <= RANGE_40K[1]:
                rows.append([f"implicit, ~40k vertices, PoCL: >= "
                             f"{TARGET_FPS_40K:.0f} fps",
                             f"{model} ({v:,} v), {dev}", f"{fps(f)} fps",
                             verdict(f >= TARGET_FPS_40K)])
            if model == "human-addon":
                rows.append([f"implicit, human-addon, PoCL: >= "
                             f"{TARGET_FPS_HUMAN:.0f} fps",
                             f"{model} ({v:,} v), {dev}", f"{fps(f)} fps",
                             verdict(f >= TARGET_FPS_HUMAN)])
    for model, runs in models.items():
        for d in sorted(results.devices):
            cl = runs.get(f"opencl:{d}")
            r = implicit_over_dqs(runs, d)
            if not cl or r is None:
                continue
            v = int(cl["vertices"])
            if RANGE_170K[0] <= v <= RANGE_170K[1]:
                rows.append([f"implicit / DQS, ~170k vertices, same device: "
                             f"<= {TARGET_RATIO_170K:.0f}x",
                             f"{model} ({v:,} v), {results.device_name(d)}",
                             ratio_cell(runs, d),
                             verdict(r <= TARGET_RATIO_170K)])
    for model, runs in models.items():
        ref = runs.get("reference")
        for d in cpu:
            cl = runs.get(f"opencl:{d}")
            if not cl or not ref or int(cl["vertices"]) < SPEEDUP_MIN_VERTICES:
                continue
            s = to_ms(ref) / to_ms(cl)
            rows.append([f"implicit, OpenCL on PoCL over the 1-thread CPU "
                         f"reference: >= {TARGET_SPEEDUP}x",
                         f"{model} ({int(cl['vertices']):,} v), "
                         f"{results.device_name(d)}", ratio(s),
                         verdict(s >= TARGET_SPEEDUP)])
    gpus = results.gpu_devices()
    gpu_rows = gpu_target_rows(results)
    for path, other in recorded:
        gpu_rows += gpu_target_rows(other, f" (recorded run `{path}`)")
    rows += gpu_rows
    if not gpu_rows:
        rows.append([f"implicit, ~170k vertices, GPU: >= "
                     f"{TARGET_GPU_FPS_170K:.0f} fps",
                     "no GPU device in this run" if not gpus
                     else "no ~170k-vertex model run on the GPU",
                     "no GPU run", "not measured"])
    if len(rows) == 1 and not models:
        return lines + ["Not run (no `Implicit/` benchmark in this JSON).",
                        ""]
    return lines + table(["target", "model, device", "measured", "verdict"],
                         rows, ["l", "l", "r", "l"])


def models_section(results):
    """Vertex and joint counts of every model seen, and the subdivision
    note."""
    counts = {}
    for key, run in results.runs.items():
        model = None
        if key[0] == "Implicit" and len(key) >= 3:
            model = key[1]
        elif key[0] == "Frame" and len(key) >= 4:
            model = key[2]
        elif key[0] == "FieldBuild" and len(key) >= 3:
            model = key[1]
        if model is None:
            continue
        entry = counts.setdefault(model, {})
        if "vertices" in run:
            entry["vertices"] = int(run["vertices"])
        if "joints" in run:
            entry["joints"] = int(run["joints"])
    if not counts:
        return []
    lines = ["## Models", "",
             "The built-in procedural arm, every shared asset with a clip "
             "(`../shared/data`, see its README for credits; human-female "
             "has none, quad_skin is a single quad), and CesiumMan "
             "and human-addon subdivided 1-to-4 (`isk::subdivideRig`, skin "
             "weights interpolated; '-xN' is N times the faces). Vertex "
             "counts are after Assimp's vertex split; texture seams stay "
             "split, so the vertices do not grow exactly with the faces (last "
             "column). Joints: joints with skin weights.", ""]
    rows = []
    for m in ordered(counts, model_order(results)):
        v = counts[m].get("vertices")
        parent = re.fullmatch(r"(.+)-x\d+", m)
        base_v = counts.get(parent.group(1), {}).get("vertices") if parent \
            else None
        rows.append([m, count(v), count(counts[m].get("joints")),
                     f"{v / base_v:.1f}x {parent.group(1)}"
                     if v and base_v else ""])
    lines += table(["model", "vertices", "joints", "vertices / original"],
                   rows)
    base = counts.get("human-addon", {}).get("vertices")
    subdivided = [(m, counts[m].get("vertices")) for m in counts
                  if m.startswith("human-addon-x") and counts[m].get(
                      "vertices")]
    if base and subdivided:
        text = ", ".join(f"{m} has {v:,} ({v / base:.1f}x)"
                         for m, v in sorted(subdivided, key=lambda x: x[1]))
        hits = [m for m, v in subdivided
                if RANGE_40K[0] <= v <= RANGE_40K[1]
                or RANGE_170K[0] <= v <= RANGE_170K[1]]
        misses = [m for m, _ in subdivided if m not in hits]
        note = (" Whole 1-to-4 levels cannot be tuned: "
                + ", ".join(misses) + " fall outside the ~40k and ~170k "
                "ranges of the targets." if misses else "")
        lines += [f"human-addon has {base:,} vertices; {text}." + note, ""]
    return lines


def implicit_section(results):
    models = implicit_models(results)
    lines = ["## Implicit skinning per frame", ""]
    if not models:
        return lines + ["Not run (no `Implicit/` benchmark in this JSON).",
                        ""]
    lines += ["A frame: pose from the model's first clip -> upload the "
              "joint transforms -> DQS -> rounds of projection (with the "
              "contact stop) and tangential relaxation -> smoothing -> "
              "normals -> read back positions and normals. 'DQS' is "
              "`isk::ClSkinning` (dual quaternions and normals, with the "
              "same uploads and reads) on the same device in the same "
              "process: implicit / DQS compares like with like, and comes "
              "from `paired`, which times an implicit and a DQS frame of "
              "the same pose in turn (the two separate benchmarks run "
              "minutes apart on a machine whose speed drifts), where the "
              "run has it. The "
              "reference is `isk::CpuImplicitSkinner` on 1 thread. "
              "ms/frame is wall time per frame; stage columns are OpenCL "
              "profiling-event times (read-back: host wall time), with their "
              "share of the frame's wall time; the rest of the frame is "
              "host and queue overhead. Contact, crease and lost are "
              "vertices per frame stopped at a contact, at a crease, or lost "
              "(out of every field); tracked is the vertices the tracking "
              "moves. The timed frames step through the clip by the golden "
              "ratio.", ""]
    order = model_order(results)
    devices = sorted({split_device(b)[1] for runs in models.values()
                      for b in runs if split_device(b)[1] is not None})
    for d in devices:
        lines += [f"### {results.device_name(d)} (OpenCL device {d})", ""]
        rows, stage_rows, start_rows = [], [], []
        for model in ordered(models, order):
            runs = models[model]
            cl = runs.get(f"opencl:{d}")
            if not cl:
                continue
            dqs, ref = runs.get(f"dqs:{d}"), runs.get("reference")
            cl_ms = to_ms(cl)
            dqs_ms = to_ms(dqs) if dqs else None
            ref_ms = to_ms(ref) if ref else None
            rows.append([model, count(cl["vertices"]),
                         count(cl.get("joints")), ms(cl_ms),
                         fps(fps_of(cl_ms)), ms(dqs_ms),
                         fps(fps_of(dqs_ms)) if dqs_ms else "n/a",
                         ratio_cell(runs, d),
                         ms(ref_ms),
                         ratio(ref_ms / cl_ms) if ref_ms else "n/a",
                         count(cl.get("tracked")), count(cl.get("contact")),
                         count(cl.get("crease")), count(cl.get("lost"))])
            stage_rows.append(
                [model, ms(cl_ms)]
                + [stage_cell(cl, s, cl_ms) for s in STAGES]
                + [f"{100 * (1 - sum(cl.get(s + '_ms', 0) for s in STAGES) / cl_ms):.0f}%"])
            if "setup_ms" in cl:
                start_rows.append([model, count(cl["vertices"]),
                                   ms(cl["setup_ms"]),
                                   ms(cl.get("first_frame_ms")), ms(cl_ms)])
        lines += table(["model", "vertices", "joints", "implicit ms/frame",
                        "implicit fps", "DQS ms/frame", "DQS fps",
                        "implicit / DQS", "reference ms/frame",
                        "OpenCL speed-up over reference", "tracked",
                        "contact", "crease", "lost"], rows)
        lines += ["Where the implicit frame's time goes (ms, % of the "
                  "frame):", ""]
        lines += table(["model", "frame ms"] + [s for s in STAGES]
                       + ["not in a stage"], stage_rows)
        if start_rows:
            lines += ["Start-up of the skinner from built fields (setup: "
                      "tracking mesh, uploads, program builds from PoCL's "
                      "disk cache when warm) and its first frame (PoCL "
                      "compiles each kernel at its first launch), beside a "
                      "steady frame:", ""]
            lines += table(["model", "vertices", "setup ms", "first frame ms",
                            "steady frame ms"], start_rows)
    ref_rows = []
    for model in ordered(models, order):
        ref = models[model].get("reference")
        if not ref:
            continue
        r_ms = to_ms(ref)
        ref_rows.append(
            [model, ms(r_ms)]
            + [stage_cell(ref, s, r_ms) for s in STAGES])
    if ref_rows:
        lines += ["### CPU reference, 1 thread: stages", ""]
        lines += table(["model", "frame ms"] + list(STAGES), ref_rows)
    return lines


LEVERS = ("all", "no-neighbourhoods", "no-neighbourhood-cells",
          "no-march-order", "no-occupied-cells", "no-value-bounds",
          "no-lane-tests", "no-active-vertices", "no-pair-bounds",
          "half-grids", "sigma-0.5",
          "sigma-0.7", "sigma-1", "no-fold-guard", "no-tilt-guard",
          "strain-limit-steps-16", "no-restore-again", "union-operator",
          "history-tracking")


def moved(run):
    """The lever frame's distance from its paired frame (over the
    diagonal): mean / largest / share beyond 1e-3; n/a in older JSON."""
    if "mean_moved" not in run:
        return "n/a"
    if run["max_moved"] == 0:
        return "0 (same frames)"
    return (f"{run['mean_moved']:.1e} / {run['max_moved']:.1e} / "
            f"{100 * run['moved_beyond_1e-3']:.2f}%")


def by_model_and_device(runs):
    """Runs named <family>/<model>/<variant>:<d> as {model: {variant:d:
    run}}, and the devices d they ran on, ascending."""
    models = {}
    for key, run in runs.items():
        if len(key) == 3:
            models.setdefault(key[1], {})[key[2]] = run
    devices = sorted({split_device(b)[1] for m in models.values() for b in m
                      if split_device(b)[1] is not None})
    return models, devices


def levers_section(results):
    runs = results.family("Levers")
    lines = ["## Speed switches (`Levers/`)", ""]
    if not runs:
        return lines + ["Not run (no `Levers/` benchmark in this JSON).", ""]
    lines += ["The implicit frame of `Implicit/` with one of the tracking's "
              "speed switches (`SurfaceTrackingOptions`) off: "
              "`field_neighbourhoods` (a vertex inside its home field's "
              "support box samples only the fields whose posed boxes meet "
              "that box, instead of every field), `neighbourhood_cells` "
              "(each home field's box cut into cells, a vertex sampling "
              "only the fields that can be non-zero in its cell; "
              "'no-neighbourhood-cells' sets 1, the whole box; the device's "
              "choice is 4 per axis on a CPU device for a character with at "
              "least 100 tracked vertices per field, 1 elsewhere), "
              "`march_order` (the "
              "projection marches the vertices by home field and along a "
              "Morton curve of their rest positions, instead of by index) "
              "and `occupied_cells` (a field sample in a grid cell whose 8 "
              "nodes are all zero skips the cell's loads; "
              "`isk::occupiedCells`, held on the device as the zero bytes "
              "of the value bounds below, so that switching it off also "
              "switches those off) and `value_bounds` (the projection skips "
              "a field whose value bound in the cell, one byte per cell, "
              "`isk::cellValueBounds`, shows it can change nothing: below "
              "the home field's value and the best so far) and "
              "`lane_tests` (on a CPU device the projection tests a cell's "
              "listed fields' spheres and grid boxes eight at a time, in "
              "float8 lanes, instead of one by one) and "
              "`active_vertices` (the relaxation launches skip the stopped "
              "vertices, the diffusion and Laplacian launches the vertices "
              "out of reach of every contact and crease vertex, instead of "
              "copying them) and `pair_bounds` (a blend or bulge pair one of "
              "whose fields the value bounds skipped is composed only where "
              "its operator's bound over the two fields' values or bounds "
              "exceeds the composed value so far, instead of sampling that "
              "field again). "
              "None changes the result (tests compare the frames bit for "
              "bit); 'all' has every switch on. 'half-grids' is the other "
              "way round: every switch on, and the grids rounded to half "
              "precision (`isk::useHalfPrecisionGrids`; stored as halves "
              "on the device), which moves the result slightly "
              "(docs/performance.md); so does 'sigma-<s>': every switch on, and the "
              "projection's step size (eq. 4, `SurfaceTrackingOptions::"
              "sigma`) s instead of the paper's 0.35, which the paper "
              "calls a compromise between speed of convergence and "
              "accuracy; and 'no-fold-guard': every switch on, and the "
              "strain limit without its fold guard "
              "(`SurfaceTrackingOptions::fold_guard`, docs/algorithm.md), "
              "so that 'frame / all' below 1 is what the guard costs; and "
              "'no-tilt-guard': every switch on, and the fold guard "
              "without its tilt guard (`SurfaceTrackingOptions::"
              "tilt_guard_degrees` 0), so that 'frame / all' below 1 is "
              "what the tilt guard costs; and "
              "'strain-limit-steps-16': every switch on, and the strain "
              "limit in 16 Jacobi steps instead of the default 32 "
              "(`SurfaceTrackingOptions::strain_limit_steps`, "
              "docs/algorithm.md), so that 'frame / all' below 1 is what "
              "the steps beyond 16 cost; and "
              "'no-restore-again': every switch on, and no second volume "
              "restoration after the strain limit "
              "(`SurfaceTrackingOptions::restore_again_steps` 0, "
              "docs/algorithm.md), so that 'frame / all' below 1 is what "
              "the second restoration and its steps cost; and "
              "'union-operator': every switch on, and the fields composed "
              "with the union at every joint (the paper's default, "
              "`--operator union`) instead of the library's default, which "
              "blends at the joints of mirrored limbs "
              "(`CompositionOptions::limb_operator`), so that 'frame / all' "
              "below 1 is what the blend costs; and 'history-tracking': "
              "every switch on, and each frame started from the last "
              "frame's result (`ImplicitSkinnerOptions::tracking_mode`, "
              "docs/algorithm.md), so that 'frame / all' above 1 is what "
              "the history mode costs. "
              "'moved' says how far each frame lies from the "
              "paired frame of the same pose: the mean and the largest "
              "distance of a vertex, over the rest mesh's bounding-box "
              "diagonal, and the share of vertices farther than 1e-3 of "
              "it (0 for the switches that keep the result). Each "
              "benchmark times its "
              "frames side by side with the same poses on a second skinner "
              "with every switch on, the two in turn: 'frame / all' is the "
              "ratio of those interleaved frames (on a shared machine whose "
              "speed drifts, benchmarks run one after the other can be tens "
              "of percent apart). ms/frame is the switched frame's wall "
              "time with its read-back, 'paired' the frames it was timed "
              "against.", ""]
    models, devices = by_model_and_device(runs)
    for d in devices:
        rows = []
        for model in ordered(models, model_order(results)):
            base = models[model].get(f"all:{d}")
            for lever in LEVERS:
                run = models[model].get(f"{lever}:{d}")
                if not run:
                    continue
                # Interleaved runs carry their own frame and ratio; older
                # JSON (one benchmark after the other) only the run's time.
                frame = run.get("frame_ms") or to_ms(run)
                if run.get("frame_over_all"):
                    versus = ratio(run["frame_over_all"])
                elif base:
                    versus = ratio(frame / to_ms(base))
                else:
                    versus = "n/a"
                rows.append([model, lever, ms(frame), fps(fps_of(frame)),
                             ms(run.get("projection_ms")),
                             ms(run.get("all_frame_ms")), versus,
                             moved(run)])
        if rows:
            lines += [f"### {results.device_name(d)} (OpenCL device {d})",
                      ""]
            lines += table(["model", "switches", "ms/frame", "fps",
                            "projection ms", "paired 'all' ms/frame",
                            "frame / all",
                            "moved: mean / largest / beyond 1e-3"], rows,
                           ["l", "l", "r", "r", "r", "r", "r", "r"])
    return lines


def crowd_section(results):
    runs = results.family("Crowd")
    lines = ["## Crowds: several characters per launch (`Crowd/`)", ""]
    if not runs:
        return lines + ["Not run (no `Crowd/` benchmark in this JSON).", ""]
    lines += ["n instances of a model, each at its own pose of the clip and "
              "apart from the others, skinned by one `isk::ImplicitCrowd` "
              "(every stage of the frame one launch over the vertices of "
              "all instances, one read-back) and by n `ImplicitSkinner`s "
              "(one per instance, the same fields), the two frames of the "
              "same poses in turn. 'mixed' is one crowd of every model "
              "above, characters of different sizes, 1 or 4 instances of "
              "each (`Crowd/mixed/x<n>`). The frames are the same vertex "
              "for vertex (tests check it). ms/frame is the wall time of "
              "the whole crowd's frame with its read-backs; 'separate / "
              "crowd' above 1 means the crowd pays.", ""]
    models, devices = by_model_and_device(runs)
    for d in devices:
        rows = []
        for model in ordered(models, model_order(results)):
            sizes = sorted(
                (int(split_device(b)[0][1:]), run)
                for b, run in models[model].items()
                if split_device(b)[1] == d
                and re.fullmatch(r"x\d+", split_device(b)[0]))
            for n, run in sizes:
                crowd_ms = run.get("crowd_ms")
                # Crowd/mixed/x<n>: n instances of each character.
                instances = int(run.get("instances") or n)
                characters = int(run.get("characters") or 1)
                label = (f"{model} ({characters} characters)"
                         if characters > 1 else model)
                rows.append([label, str(instances),
                             count(run.get("vertices")),
                             ms(crowd_ms),
                             ms(crowd_ms / instances if crowd_ms else None),
                             ms(run.get("separate_ms")),
                             ratio(run.get("separate_over_crowd"))])
        if rows:
            lines += [f"### {results.device_name(d)} (OpenCL device {d})",
                      ""]
            lines += table(["model", "instances", "vertices (all)",
                            "crowd ms/frame", "ms per instance",
                            "separate ms/frame", "separate / crowd"], rows,
                           ["l", "r", "r", "r", "r", "r", "r"])
    return lines


def paper_section(results):
    models = implicit_models(results)
    lines = ["## The paper's Table 1 beside ours", ""]
    ours = []
    for model, runs in models.items():
        for b, run in runs.items():
            backend, d = split_device(b)
            if backend == "opencl" and runs.get(f"dqs:{d}"):
                ours.append((model, d, run, runs[f"dqs:{d}"]))
    if not ours:
        return lines + ["Not run (no `Implicit/` benchmark with its DQS "
                        "twin in this JSON).", ""]
    lines += ["The paper's figures (Vaillant et al. 2013, Table 1: GTX 680, "
              "fps) next to our model of the nearest vertex count (on a log "
              "scale) on each OpenCL device of this run. The paper's "
              "implicit / DQS is its DQS fps over its implicit fps ('>' "
              "where the paper gives a bound); ours is measured time over "
              "time on one device (frames timed side by side where the run "
              "has `paired`).", ""]
    rows = []
    for name, vertices, paper_implicit, paper_dqs in PAPER_TABLE_1:
        bound = paper_dqs.startswith(">")
        dqs_value = float(paper_dqs.lstrip(">"))
        paper_ratio = (">" if bound else "") + ratio(
            dqs_value / paper_implicit, 1)
        for d in sorted({o[1] for o in ours}):
            candidates = [o for o in ours if o[1] == d]
            model, _, cl, dqs = min(
                candidates,
                key=lambda o: abs(math.log(o[2]["vertices"] / vertices)))
            cl_ms, dqs_ms = to_ms(cl), to_ms(dqs)
            rows.append([name, f"{vertices:,}", str(paper_implicit),
                         paper_dqs, paper_ratio, model,
                         count(cl["vertices"]), results.device_name(d),
                         fps(fps_of(cl_ms)), fps(fps_of(dqs_ms)),
                         ratio(implicit_over_dqs(models[model], d), 1)])
    lines += table(["paper model", "vertices", "implicit fps", "DQS fps",
                    "implicit / DQS", "our model", "vertices", "our device",
                    "implicit fps", "DQS fps", "implicit / DQS"], rows,
                   ["l", "r", "r", "r", "r", "l", "r", "l", "r", "r", "r"])
    return lines


def frame_section(results):
    runs = {}
    for key, run in results.family("Frame").items():
        if len(key) >= 4:
            runs.setdefault((key[2], key[3]), {})[key[1]] = run
    lines = ["## Geometric skinning per frame (LBS, DQS)", ""]
    if not runs:
        return lines + ["Not run (no `Frame/` benchmark in this JSON).", ""]
    lines += ["A frame: pose from the clip -> upload joint transforms -> "
              "skinning kernel -> normals kernel -> read back positions and "
              "normals (OpenCL), or the same work in `isk::CpuSkinning` on 1 "
              "thread. Kernel columns are OpenCL profiling-event times.", ""]
    order = model_order(results)
    devices = sorted({split_device(b)[1] for r in runs.values() for b in r
                      if split_device(b)[1] is not None})
    for d in devices:
        rows = []
        for (model, method) in ordered(
                runs, [(m, x) for m in order for x in ("lbs", "dqs")]):
            backends = runs[(model, method)]
            cl = backends.get(f"opencl:{d}")
            if not cl:
                continue
            ref = backends.get("reference")
            cl_ms = to_ms(cl)
            ref_ms = to_ms(ref) if ref else None
            rows.append([model, count(cl["vertices"]), method, ms(cl_ms),
                         fps(fps_of(cl_ms)), ms(ref_ms),
                         ratio(ref_ms / cl_ms) if ref_ms else "n/a",
                         ms(cl.get("upload_ms")), ms(cl.get("skinning_ms")),
                         ms(cl.get("normals_ms")), ms(cl.get("readback_ms"))])
        lines += [f"### {results.device_name(d)} (OpenCL device {d})", ""]
        lines += table(["model", "vertices", "method", "OpenCL ms/frame",
                        "fps", "reference ms/frame",
                        "OpenCL speed-up over reference", "upload ms",
                        "skinning kernel ms", "normals kernel ms",
                        "read-back ms"], rows,
                       ["l", "r", "l"] + ["r"] * 8)
    return lines


def scaling_section(results):
    lines = ["## Scaling", ""]
    fam = results.family("Scaling")
    if not fam:
        return lines + ["Not run (no `Scaling/` benchmark in this JSON).",
                        ""]
    def spread_of(series, counter, digits_format):
        values = sorted({int(r[counter]) for k, r in fam.items()
                         if len(k) >= 4 and k[1] == series and counter in r})
        if not values:
            return "n/a"
        if values[0] == values[-1]:
            return digits_format(values[0])
        return (f"{digits_format(values[0])} to "
                f"{digits_format(values[-1])}")

    lines += ["Procedural closed cylinders (`isk::makeCylinderRig`: bones "
              "of length 3, radius 1, nearly square triangles), every inner "
              "joint bent 30 to 50 degrees alternately up and down (a "
              "zigzag; `bench/bench_support.cpp`), implicit skinning "
              "(`isk::ImplicitSkinner`) and DQS (`isk::ClSkinning`) per "
              "frame on each device, same frame and counters as above. "
              "Vertex series: "
              + spread_of("vertices", "joints", str) + " bones, "
              + spread_of("vertices", "vertices", lambda v: f"{v:,}")
              + " vertices; bone series: "
              + spread_of("joints", "joints", str) + " bones, "
              + spread_of("joints", "vertices", lambda v: f"{v:,}")
              + " vertices.", ""]
    for series, title, first in (("vertices", "Vertex count", "target"),
                                 ("joints", "Bone count", "bones")):
        runs = {}
        for key, run in fam.items():
            if len(key) >= 4 and key[1] == series:
                runs.setdefault(key[2], {})[key[3]] = run
        if not runs:
            lines += [f"### {title}: not run", ""]
            continue
        devices = sorted({split_device(b)[1] for r in runs.values()
                          for b in r if split_device(b)[1] is not None})
        for d in devices:
            rows = []
            sort_counter = "vertices" if series == "vertices" else "joints"
            for point in sorted(
                    runs, key=lambda p: next(
                        (r.get(sort_counter, 0) for r in runs[p].values()),
                        0)):
                cl = runs[point].get(f"implicit:{d}")
                dqs = runs[point].get(f"dqs:{d}")
                paired = runs[point].get(f"paired:{d}")
                if not cl and paired and paired.get("implicit_ms"):
                    # A run of the paired frames alone (a recorded GPU run):
                    # their own times, no stage columns.
                    implicit_ms = paired["implicit_ms"]
                    rows.append([point, count(paired.get("vertices")),
                                 count(paired.get("joints")), ms(implicit_ms),
                                 fps(fps_of(implicit_ms)),
                                 ms(paired.get("dqs_ms")),
                                 ratio_cell(runs[point], d, "implicit"),
                                 "n/a", "n/a", "n/a", "n/a",
                                 f"{1e6 * implicit_ms / paired['vertices']:.0f}"
                                 if paired.get("vertices") else "n/a",
                                 "n/a"])
                    continue
                if not cl:
                    continue
                cl_ms = to_ms(cl)
                dqs_ms = to_ms(dqs) if dqs else None
                rows.append([point, count(cl["vertices"]),
                             count(cl.get("joints")), ms(cl_ms),
                             fps(fps_of(cl_ms)), ms(dqs_ms),
                             ratio_cell(runs[point], d, "implicit"),
                             ms(cl.get("projection_ms")),
                             ms(cl.get("relaxation_ms")),
                             ms(cl.get("smoothing_ms")),
                             ms(cl.get("normals_ms")),
                             f"{1e6 * cl_ms / cl['vertices']:.0f}",
                             count(cl.get("contact"))])
            lines += [f"### {title}, {results.device_name(d)} (OpenCL "
                      f"device {d})", ""]
            lines += table([first, "vertices", "bones", "implicit ms/frame",
                            "fps", "DQS ms/frame", "implicit / DQS",
                            "projection ms", "relaxation ms", "smoothing ms",
                            "normals ms", "ns per vertex", "contact"], rows)
    return lines


def fields_section(results):
    lines = ["## Field evaluation", ""]
    union = {}
    for key, run in results.family("FieldEval").items():
        if len(key) >= 3:
            union.setdefault(key[2], {})[key[1]] = run
    composed = {}
    for key, run in results.family("FieldCompose").items():
        if len(key) >= 4:
            composed.setdefault((key[3], key[1]), {})[key[2]] = run
    if not union and not composed:
        return lines + ["Not run (no `FieldEval/` or `FieldCompose/` "
                        "benchmark in this JSON).", ""]
    lines += ["Composed field value and gradient at every skinned vertex of "
              "a clip frame (what each projection step does once per "
              "vertex): the 1-thread reference against the OpenCL kernel "
              "with the 32^3 grids in a buffer or in a 3D image, points "
              "already on the device. Union: max of all fields; blend and "
              "bulge: that operator at every joint (operator tables), "
              "compared with the union of the same run.", ""]
    order = model_order(results)
    devices = sorted({split_device(b)[1] for r in list(union.values())
                      + list(composed.values()) for b in r
                      if split_device(b)[1] is not None})
    rows = []
    for (model, op) in ordered(
            set(list(composed) + [(m, "union") for m in union]),
            [(m, o) for m in order for o in ("union", "blend", "bulge")]):
        backends = union.get(model, {}) if op == "union" else composed[
            (model, op)]
        base = union.get(model, {})
        ref = backends.get("reference")
        any_run = ref or next(iter(backends.values()), None)
        if not any_run:
            continue
        row = [model, op, count(any_run.get("points")),
               (f"{any_run['fields_per_point']:.1f} of "
                f"{int(any_run['fields'])}"
                if "fields_per_point" in any_run else
                count(any_run.get("fields"))),
               ms(to_ms(ref)) if ref else "n/a"]
        for d in devices:
            for storage in ("buffer", "image"):
                run = backends.get(f"opencl-{storage}:{d}")
                cell = ms(to_ms(run)) if run else "n/a"
                if run and op != "union" and base.get(
                        f"opencl-{storage}:{d}"):
                    cell += (f" ({to_ms(run) / to_ms(base[f'opencl-{storage}:{d}']):.2f}x"
                             " union)")
                row.append(cell)
            buf = backends.get(f"opencl-buffer:{d}")
            row.append(ratio(to_ms(ref) / to_ms(buf))
                       if ref and buf else "n/a")
        rows.append(row)
    header = ["model", "operator", "points", "fields per point",
              "reference ms"]
    for d in devices:
        header += [f"dev {d} buffer ms", f"dev {d} image ms",
                   f"dev {d} buffer speed-up"]
    lines += [", ".join(f"dev {d}: {results.device_name(d)}"
                        for d in devices) + ".", ""]
    lines += table(header, rows, ["l", "l"] + ["r"] * (len(header) - 2))
    return lines


def precompute_section(results):
    lines = ["## Precompute and start-up", ""]
    any_data = False
    builds = {}
    for key, run in results.family("FieldBuild").items():
        if len(key) >= 3:
            builds.setdefault(key[1], {})[key[2]] = run
    lines += ["### Fit and bake per model (`FieldBuild/`)", ""]
    if builds:
        any_data = True
        lines += ["`isk::buildImplicitFields`: partition, Poisson-disk "
                  "sampling, HRBF fits, 32^3 grid baking, operators per "
                  "joint, iso values, on 1 thread and on all threads "
                  "(subdivided models: all threads only). Stage columns are "
                  "from the all-threads run. Cached load: the same build "
                  "with the field cache hitting (`FieldBuild/<model>/"
                  "cached-load`: samples, fits and grids read from "
                  "`ISK_CACHE_DIR`, composition and iso values recomputed), "
                  "and its speed-up over the all-threads build.", ""]
        rows = []
        for model in ordered(builds, model_order(results)):
            by = builds[model]
            threads = sorted((t for t in by if t.startswith("threads:")),
                             key=lambda t: int(t.split(":")[-1]))
            if not threads:
                continue
            one = by.get("threads:1")
            many = by[threads[-1]]
            cached = by.get("cached-load")
            cached_text = "n/a"
            if cached:
                cached_text = ms(to_ms(cached))
                if to_ms(cached) and to_ms(many):
                    cached_text += f" ({to_ms(many) / to_ms(cached):.1f}x)"
            rows.append([model, count(many.get("vertices")),
                         count(many.get("joints")), count(many.get("fields")),
                         ms(many.get("field_MiB"), 1),
                         ms(to_ms(one)) if one else "n/a",
                         f"{ms(to_ms(many))} ({threads[-1].split(':')[-1]})",
                         ms(many.get("sampling_ms")),
                         ms(many.get("fitting_ms")),
                         ms(many.get("baking_ms")),
                         ms(many.get("operators_ms")),
                         ms(many.get("iso_ms")), cached_text])
        lines += table(["model", "vertices", "joints", "fields", "field MiB",
                        "1 thread ms", "all threads ms (threads)",
                        "sampling ms", "fitting ms", "baking ms",
                        "operators ms", "iso ms",
                        "cached load ms (speed-up)"], rows)
    else:
        lines += ["Not run.", ""]

    lines += ["### Operator tables (`OperatorTable/`)", ""]
    tables = {}
    for key, run in results.family("OperatorTable").items():
        if len(key) >= 3:
            tables.setdefault(key[1], {})[key[2]] = run
    if tables:
        any_data = True
        lines += ["Baking one 128^3 table (value and two partials per node) "
                  "on every hardware thread, against loading and validating "
                  "it from the on-disk cache (`ISK_CACHE_DIR`, default "
                  "`$XDG_CACHE_HOME/isk` or `~/.cache/isk`; file in the OS "
                  "page cache), which is what a process after the first "
                  "does.", ""]
        rows = []
        for op in ordered(tables, ["blend", "bulge"]):
            bake, load = tables[op].get("bake"), tables[op].get("cached-load")
            any_run = bake or load
            rows.append([op, ms(any_run.get("table_MiB"), 0),
                         ms(to_ms(bake)) if bake else "n/a",
                         ms(to_ms(load)) if load else "n/a",
                         ratio(to_ms(bake) / to_ms(load), 1)
                         if bake and load else "n/a"])
        lines += table(["operator", "MiB", "bake ms", "cached load ms",
                        "load speed-up"], rows, ["l", "r", "r", "r", "r"])
    else:
        lines += ["Not run.", ""]

    lines += ["### OpenCL program builds (`ProgramBuild/`)", ""]
    progs = {}
    for key, run in results.family("ProgramBuild").items():
        # ProgramBuild/<kernel file, in its stage folder>/<mode>:<device>
        if len(key) >= 3:
            mode, d = split_device(key[-1])
            if d is not None:
                progs.setdefault(("/".join(key[1:-1]), d), {})[mode] = run
    if progs:
        any_data = True
        lines += ["clCreateProgramWithSource + clBuildProgram of each "
                  "embedded kernel file with the library's options. Cold: a "
                  "fresh context and a unique define, so the driver's disk "
                  "cache (POCL_CACHE_DIR) misses; warm: a fresh context, "
                  "same options, the driver's cache hits; in-process: the "
                  "library's per-context program cache. PoCL compiles each "
                  "kernel's work-group function at its first launch, which "
                  "is not in these figures (see 'first frame' above); the "
                  "compiler's own start-up, once per process, is in the "
                  "first cold build of the process only.", ""]
        rows = []
        for (kernel, d) in sorted(progs, key=lambda k: (k[1], k[0])):
            m = progs[(kernel, d)]
            rows.append([kernel, results.device_name(d),
                         ms(to_ms(m["cold"])) if "cold" in m else "n/a",
                         ms(to_ms(m["warm"])) if "warm" in m else "n/a",
                         ms(1000 * to_ms(m["in-process"]), 3)
                         if "in-process" in m else "n/a"])
        lines += table(["kernel file", "device", "cold ms", "warm ms",
                        "in-process us"], rows, ["l", "l", "r", "r", "r"])
    else:
        lines += ["Not run.", ""]
    lines += ["### Import, in-process and isolated (`Import/`)", ""]
    imports = {}
    for key, run in results.family("Import").items():
        if len(key) >= 3:
            imports.setdefault(key[1], {})[key[2]] = run
    if imports:
        any_data = True
        lines += ["`isk::importRig` of each shared asset (file in the OS "
                  "page cache) in the calling process, and isolated: in a "
                  "child process with a time limit (fork, import, the rig "
                  "sent back over a pipe), which a file that hangs or "
                  "crashes Assimp cannot take down.", ""]
        rows = []
        for model in imports:
            inside = imports[model].get("in-process")
            isolated = imports[model].get("isolated")
            any_run = inside or isolated
            rows.append([model, count(any_run.get("vertices")),
                         ms(to_ms(inside)) if inside else "n/a",
                         ms(to_ms(isolated)) if isolated else "n/a",
                         ratio(to_ms(isolated) / to_ms(inside), 1)
                         if inside and isolated else "n/a"])
        lines += table(["model", "vertices", "in-process ms", "isolated ms",
                        "isolated / in-process"], rows,
                       ["l", "r", "r", "r", "r"])
    else:
        lines += ["Not run.", ""]
    return lines if any_data else ["## Precompute and start-up", "",
                                   "Not run.", ""]


def bench_device_of(results, name):
    """The OpenCL device index of this run's isk_bench with that name."""
    return next((d for d, v in sorted(results.devices.items())
                 if v["name"] == name), None)


def not_measured(report):
    if report is None:
        return "not run (this JSON has no figures of it)"
    if "skipped" in report:
        return f"skipped: {report['skipped']}"
    if "failed" in report:
        return f"failed: {report['failed']}"
    if not report.get("models"):
        return "no model measured (assets missing: " + ", ".join(
            report.get("missing", [])) + ")"
    return None


def python_blender_section(results, figures):
    """The Python module's and Blender's frames (bench/python_frames.py and
    bench/blender_frames.py, run after isk_bench; their JSON is stored in
    this run's JSON under "isk_python_blender")."""
    lines = ["## Python and Blender", ""]
    if figures is None:
        return lines + ["Not run (this JSON has no `isk_python_blender` "
                        "figures: `bench/python_frames.py` and "
                        "`bench/blender_frames.py` did not run).", ""]
    lines += ["What a frame costs through the `isk` Python module and "
              "through the Blender add-on, beside the library's own frame; "
              "each ratio comes from frames measured in one process. "
              "Figures are medians over the frames after a warm-up "
              "(isk_bench's figures are means).", ""]
    python = figures.get("python")
    why = not_measured(python)
    lines += ["### Python module (`bench/python_frames.py`)", ""]
    if why:
        lines += [f"Python module: {why}.", ""]
    else:
        lines += [
            f"On {python['device']}, {python['frames']} frames per model "
            f"and method after {python['warmup']} warm-up frames, in "
            f"{python['wall_seconds']:.0f} s: "
            f"`{python.get('command', 'python3 bench/python_frames.py')}`. "
            "'Python' is the wall time of "
            "`positions, normals = skinner.deform(pose)` (`isk."
            "ImplicitSkinner`, `isk.GeometricSkinner` with DQS), the pose's "
            "matrices computed beforehand: the matrices' conversion, the "
            "C++ frame, the two read-backs and the NumPy arrays. 'C++' is "
            "the C++ part of the same calls as the library times it: for "
            "implicit `last_frame_ms` (`ImplicitSkinner::run`) plus "
            "`stage_times['readback']` (`readPositions`, `readNormals`), "
            "the frame that `Implicit/<model>/opencl` times; for DQS "
            "`last_frame_ms` alone (`ClSkinning::run` with normals: the "
            "module does not expose the DQS read-back), so the DQS "
            "'Python / C++' also counts the read-back and bounds the "
            "module's overhead from above. The poses are those of "
            "isk_bench's `Implicit/` family (the first clip, stepped by "
            "the golden ratio), the implicit and DQS frames of a pose in "
            "turn; the last two columns set the Python call against this "
            "run's `Implicit/<model>/opencl` and `dqs` ms/frame (the same "
            "frames with their read-backs, in another process, minutes "
            "apart).", ""]
        rows = []
        for m in python["models"]:
            d = bench_device_of(results, m.get("device"))
            runs = implicit_models(results).get(m["model"], {})
            for name, label, backend in (("implicit", "implicit", "opencl"),
                                         ("dqs", "DQS", "dqs")):
                r = m[name]
                bench = runs.get(f"{backend}:{d}") if d is not None else None
                bench_ms = to_ms(bench) if bench else None
                rows.append([m["model"], count(m["vertices"]), label,
                             ms(r["python_ms"]), ms(r["cpp_ms"]),
                             ratio(r["python_over_cpp"]),
                             ms(r["overhead_ms"]), ms(bench_ms),
                             ratio(r["python_ms"] / bench_ms)
                             if bench_ms else "n/a"])
        lines += table(["model", "vertices", "method", "Python ms/frame",
                        "C++ ms/frame (same calls)", "Python / C++",
                        "Python - C++ ms", "isk_bench ms/frame",
                        "Python / isk_bench"], rows,
                       ["l", "r", "l", "r", "r", "r", "r", "r", "r"])
        if python.get("missing"):
            lines += ["Assets missing: " + ", ".join(python["missing"])
                      + ".", ""]
    blender = figures.get("blender")
    why = not_measured(blender)
    lines += ["### Blender add-on (`bench/blender_frames.py`)", ""]
    if why:
        lines += [f"Blender: {why}.", ""]
    else:
        lines += [
            f"Blender {blender['blender']}, headless, on "
            f"{blender.get('device') or 'n/a'}, in "
            f"{blender['wall_seconds']:.0f} s: "
            f"`{blender.get('command', 'blender -b --factory-startup --python bench/blender_frames.py')}`. "
            "Each asset is imported with Blender's glTF importer "
            "and its largest skinned mesh played through its clip (again "
            f"until at least {blender['min_frames']} frames are timed, "
            f"after {blender['warmup']} warm-up frames): with the Armature "
            "modifier alone, then with the add-on built on it (from the add-"
            "on zip) for DQS and for implicit skinning. 'frame' is the wall "
            "time of `scene.frame_set(frame)`: the action, the depsgraph "
            "(the modifier, or the add-on's shape key) and the add-on's "
            "handlers; 'handlers' is the add-on's frame-change and "
            "depsgraph handlers within it (the skinning matrices from the "
            "pose bones, the module's `deform`, the shape key's write); "
            "'module' is the add-on's `last_frame_ms`, the module's C++ "
            "frame without its read-back. Blender's vertex counts are its "
            "own (it splits the mesh differently from Assimp).", ""]
        rows = []
        for m in blender["models"]:
            if "error" in m:
                rows.append([m["asset"], "n/a", m["error"], "n/a", "n/a",
                             "n/a", "n/a"])
                continue
            label = (f"{m['asset']} ({count(m['vertices'])} v, "
                     f"{m['bones']} bones, {m['clip_frames']} clip frames)")
            rows.append([label, "Armature modifier",
                         ms(m["armature"]["frame_ms"]), "1.00x", "", "", ""])
            for mode, name in (("dqs", "add-on, DQS"),
                               ("implicit", "add-on, implicit")):
                r = m.get(mode, {})
                if "error" in r:
                    rows.append([label, name, r["error"], "n/a", "n/a",
                                 "n/a", "n/a"])
                    continue
                handler = r.get("handler_ms")
                rows.append([label, name, ms(r.get("frame_ms")),
                             ratio(r.get("over_armature")), ms(handler),
                             ms(r.get("module_ms")),
                             ms(r["frame_ms"] - handler)
                             if handler is not None else "n/a"])
        lines += table(["asset", "deformed by", "frame ms",
                        "frame / Armature modifier", "handlers ms",
                        "module ms", "frame outside the handlers ms"], rows,
                       ["l", "l", "r", "r", "r", "r", "r"])
        if blender.get("missing"):
            lines += ["Assets missing: " + ", ".join(blender["missing"])
                      + ".", ""]
    return lines


def failed_section(results):
    if not results.failed:
        return []
    lines = ["## Benchmarks that reported an error", ""]
    def cell(text):
        # One line, no table breaks; long build logs cut.
        text = " ".join(text.split()).replace("|", "\\|")
        return text if len(text) <= 300 else text[:300] + " ..."

    lines += table(["benchmark", "error"],
                   [[cell(n), cell(e)] for n, e in results.failed],
                   ["l", "l"])
    return lines


def demoted(lines):
    """Markdown lines with every heading one level deeper."""
    return ["#" + l if l.startswith("#") else l for l in lines]


def recorded_section(path, results):
    """A run recorded on another machine (bench/results/*.json): where it
    ran, how, and its per-frame, lever, field and start-up tables."""
    ctx = results.context
    devices = ", ".join(v["name"] for _, v in sorted(results.devices.items()))
    lines = [f"## Recorded run: {devices or 'no OpenCL device'}", "",
             f"From `{path}`, a run on another machine kept in the "
             "repository (the machine above has no such device). Compare "
             "figures within this section only.", ""]
    lines += [f"- Run of {ctx.get('date', '?')} on host "
              f"`{ctx.get('host_name', '?')}`: {ctx.get('num_cpus', '?')} "
              f"CPUs at {ctx.get('mhz_per_cpu', '?')} MHz."]
    for d, v in sorted(results.devices.items()):
        lines.append(f"- OpenCL device {d} ({v['type']}): {v['name']}.")
    if ctx.get("isk_run_note"):
        lines.append(f"- {ctx['isk_run_note']}")
    if ctx.get("isk_run_command"):
        lines += ["", "How it was run:", "", "```sh", ctx["isk_run_command"],
                  "```"]
    lines.append("")
    body = []
    if results.family("Implicit"):
        body += implicit_section(results)
    if results.family("Levers"):
        body += levers_section(results)
    if results.family("Crowd"):
        body += crowd_section(results)
    if results.family("Frame"):
        body += frame_section(results)
    if results.family("Scaling"):
        body += scaling_section(results)
    if results.family("FieldEval") or results.family("FieldCompose"):
        body += fields_section(results)
    if results.family("ProgramBuild") or results.family("FieldBuild"):
        body += precompute_section(results)
    return lines + demoted(body)


def render(data, command_text, elapsed=None, recorded=()):
    """The markdown of one run's JSON `data`; `recorded` holds (path, JSON)
    of runs recorded on other machines, shown after it."""
    results = Results(data)
    figures = data.get("isk_python_blender")
    if data.get("context", {}).get("isk_only_python"):
        return only_python_render(results, figures, command_text)
    recorded = [(path, Results(other)) for path, other in recorded]
    lines = []
    lines += header_section(results, command_text, elapsed)
    lines += targets_section(results, recorded)
    lines += models_section(results)
    lines += implicit_section(results)
    lines += levers_section(results)
    lines += crowd_section(results)
    lines += paper_section(results)
    lines += frame_section(results)
    lines += scaling_section(results)
    lines += precompute_section(results)
    lines += fields_section(results)
    lines += python_blender_section(results, figures)
    lines += failed_section(results)
    for path, other in recorded:
        lines += recorded_section(path, other)
    return "\n".join(lines).rstrip() + "\n"


def only_python_render(results, figures, command_text):
    """The markdown of an --only-python run: its section alone."""
    ctx = results.context
    lines = ["# Benchmarks: Python and Blender only", "",
             "Written by `bench/run_benchmarks.py --only-python` (no "
             "isk_bench run, so no isk_bench column), by the command below:",
             "", "```sh", command_text, "```", "",
             f"- Run of {ctx.get('date', '?')} on host "
             f"`{ctx.get('host_name', '?')}`: {ctx.get('num_cpus', '?')} "
             "CPUs, load average before the run "
             + ", ".join(f"{x:.2f}" for x in ctx.get("load_avg", [])) + ".",
             ""]
    lines += python_blender_section(results, figures)
    return "\n".join(lines).rstrip() + "\n"


def shown_path(path):
    """A path relative to the repository when inside it, else absolute."""
    path = os.path.abspath(path)
    inside = os.path.commonpath([path, REPO]) == REPO
    return os.path.relpath(path, REPO) if inside else path


def main():
    parser = argparse.ArgumentParser(
        description="Run isk_bench and write BENCHMARKS.md from its JSON.")
    parser.add_argument("--bench",
                        default=os.path.join(REPO, "build", "bench",
                                             "isk_bench"),
                        help="the isk_bench executable (default: "
                             "build/bench/isk_bench)")
    parser.add_argument("--json", help="where the JSON goes (default: "
                        "benchmarks.json next to the executable)")
    parser.add_argument("--out",
                        help="the markdown written (default: "
                             "bench/BENCHMARKS.md; with --only-python "
                             "python-blender.md beside the JSON)")
    parser.add_argument("--filter", help="--benchmark_filter passed on")
    parser.add_argument("--min-time", type=float,
                        help="--benchmark_min_time passed on (families with "
                             "their own minimum time or iteration count "
                             "keep it)")
    parser.add_argument("--from-json",
                        help="write the markdown from this JSON, run nothing")
    parser.add_argument("--recorded", nargs="*",
                        help="JSON of runs recorded on other machines, shown "
                             "after this run (default: bench/results/*.json;"
                             " none with an empty list)")
    parser.add_argument("--only-python", action="store_true",
                        help="run only bench/python_frames.py and "
                             "bench/blender_frames.py, no isk_bench (JSON "
                             "default: python-blender.json beside the "
                             "executable)")
    parser.add_argument("--skip-python", action="store_true",
                        help="run isk_bench alone, without the Python and "
                             "Blender frames")
    parser.add_argument("--python-module",
                        help="the folder holding the isk package (default: "
                             "python/ in the build folder of --bench)")
    parser.add_argument("--python",
                        help="the interpreter of bench/python_frames.py "
                             "(default: the build's Python3_EXECUTABLE, the "
                             "one the module is built for)")
    parser.add_argument("--blender", default="blender",
                        help="the Blender executable (default: blender)")
    parser.add_argument("--blender-zip",
                        help="the add-on zip (default: isk_blender.zip in "
                             "the build folder of --bench)")
    parser.add_argument("bench_args", nargs="*",
                        help="more isk_bench arguments (after --)")
    args = parser.parse_args()

    if args.only_python and (args.from_json or args.skip_python):
        parser.error("--only-python goes with neither --from-json nor "
                     "--skip-python")
    elapsed = None
    figures = None
    script = ["python3", "bench/run_benchmarks.py"]
    if os.path.abspath(args.bench) != os.path.join(REPO, "build", "bench",
                                                  "isk_bench"):
        script += ["--bench", shown_path(args.bench)]
    for option in ("python_module", "blender_zip", "python"):
        if getattr(args, option):
            script += ["--" + option.replace("_", "-"),
                       shown_path(getattr(args, option))]
    if args.blender != "blender":
        script += ["--blender", args.blender]
    if args.from_json:
        json_path = args.from_json
        command_text = None
    elif args.only_python:
        json_path = os.path.abspath(args.json or os.path.join(
            os.path.dirname(os.path.abspath(args.bench)),
            "python-blender.json"))
        context = {"date": datetime.datetime.now().astimezone().isoformat(
                       timespec="seconds"),
                   "host_name": platform.node(), "num_cpus": os.cpu_count(),
                   "load_avg": list(os.getloadavg()),
                   "isk_only_python": True}
        data = {"context": context, "benchmarks": [],
                "isk_python_blender": run_python_and_blender(args)}
        with open(json_path, "w") as f:
            json.dump(data, f, indent=1)
        command_text = shlex.join(script + ["--only-python"])
    else:
        json_path, command, elapsed = run_suite(args)
        if args.skip_python:
            script.append("--skip-python")
        else:
            figures = run_python_and_blender(args)
        if args.filter:
            script += ["--filter", args.filter]
        if args.min_time is not None:
            script += ["--min-time", str(args.min_time)]
        if args.bench_args:
            script += ["--"] + args.bench_args
        shown = [shown_path(command[0])] + [
            re.sub(r"^(--benchmark_out=)(/.*)$",
                   lambda m: m.group(1) + shown_path(m.group(2)), c)
            for c in command[1:]]
        command_text = (shlex.join(script) + "\n# which runs:\n"
                        + shlex.join(shown))
    with open(json_path) as f:
        data = json.load(f)
    ctx = data.setdefault("context", {})
    if command_text is None:
        # The command of the run that wrote the JSON, when this script ran it.
        command_text = ctx.get("isk_run_command") or (
            "python3 bench/run_benchmarks.py --from-json "
            + shlex.quote(json_path))
        elapsed = ctx.get("isk_run_seconds")
    else:
        ctx["isk_run_command"] = command_text
        ctx["isk_run_seconds"] = elapsed
        if figures is not None:
            data["isk_python_blender"] = figures
        with open(json_path, "w") as f:
            json.dump(data, f, indent=1)
    if args.recorded is None:
        args.recorded = sorted(
            glob.glob(os.path.join(REPO, "bench", "results", "*.json")))
    recorded = []
    for path in args.recorded:
        with open(path) as f:
            recorded.append((shown_path(path), json.load(f)))
    if args.out is None:
        args.out = (os.path.join(os.path.dirname(json_path),
                                 "python-blender.md")
                    if ctx.get("isk_only_python")
                    else os.path.join(REPO, "bench", "BENCHMARKS.md"))
    text = render(data, command_text, elapsed, recorded)
    with open(args.out, "w") as f:
        f.write(text)
    log(f"== wrote {args.out}")


if __name__ == "__main__":
    main()
