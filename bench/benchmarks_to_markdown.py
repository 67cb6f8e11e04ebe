#!/usr/bin/env python3
"""Turns isk_bench's JSON output into the tables of BENCHMARKS.md.

    build/bench/isk_bench --benchmark_out=bench.json --benchmark_out_format=json
    python3 bench/benchmarks_to_markdown.py bench.json > tables.md

Each row pairs the OpenCL and CPU-reference runs of one model and method from
the same run, so the speed-up is a ratio measured in one process. Tables are
printed for the families present: Frame (skinning), FieldBuild (offline
fields), FieldEval (field evaluation), FieldCompose (the blend or the bulge
at every joint, against FieldEval's union of the same run), OperatorTable
(baking one operator table) and Implicit (implicit skinning per frame against
DQS on the same device and against the CPU reference, same run).
"""
import json
import sys


def group_runs(data, family, min_parts, key_and_slot):
    """Runs of one family grouped by key: {key: {slot: run}}.

    key_and_slot maps a name's "/" parts to (key, slot); runs with fewer parts
    or that failed are left out.
    """
    runs = {}
    for b in data["benchmarks"]:
        parts = b["name"].split("/")
        if (len(parts) < min_parts or parts[0] != family
                or b.get("error_occurred")):
            continue
        key, slot = key_and_slot(parts)
        runs.setdefault(key, {})[slot] = b
    return runs


def frame_table(data):
    # Frame/<backend>/<model>/<method>/real_time
    runs = group_runs(data, "Frame", 4, lambda p: ((p[2], p[3]), p[1]))
    if not runs:
        return
    print("| model | vertices | method | OpenCL ms/frame | reference ms/frame "
          "| OpenCL speed-up | skinning kernel ms | normals kernel ms |")
    print("|---|---:|---|---:|---:|---:|---:|---:|")
    for (model, method), backends in runs.items():
        cl, ref = backends.get("opencl"), backends.get("reference")
        if not cl or not ref:
            continue
        cl_ms, ref_ms = cl["real_time"], ref["real_time"]
        print(f"| {model} | {int(cl['vertices'])} | {method} | {cl_ms:.3f} | "
              f"{ref_ms:.3f} | {ref_ms / cl_ms:.2f}x | "
              f"{cl['skinning_ms']:.3f} | {cl['normals_ms']:.3f} |")
    print()


def field_build_table(data):
    # FieldBuild/<model>/threads:<n>/real_time
    runs = group_runs(data, "FieldBuild", 3,
                      lambda p: (p[1], p[2].split(":")[1]))
    if not runs:
        return
    print("| model | vertices | joints | fields | field MiB | 1 thread ms "
          "| all threads ms | speed-up | sampling ms | fitting ms | baking ms "
          "| iso ms |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for model, by_threads in runs.items():
        one = by_threads.get("1")
        many = max(by_threads.items(), key=lambda kv: int(kv[0]))[1]
        if not one:
            continue
        print(f"| {model} | {int(one['vertices'])} | {int(one['joints'])} | "
              f"{int(one['fields'])} | {one['field_MiB']:.1f} | "
              f"{one['real_time']:.1f} | {many['real_time']:.1f} | "
              f"{one['real_time'] / many['real_time']:.2f}x | "
              f"{many['sampling_ms']:.1f} | {many['fitting_ms']:.1f} | "
              f"{many['baking_ms']:.1f} | {many['iso_ms']:.1f} |")
    print()


def field_eval_table(data):
    # FieldEval/<backend>/<model>/real_time
    runs = group_runs(data, "FieldEval", 3, lambda p: (p[2], p[1]))
    if not runs:
        return
    print("| model | points | fields | reference ms | OpenCL buffer ms "
          "| OpenCL image ms | buffer speed-up | image time / buffer time |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for model, backends in runs.items():
        ref = backends.get("reference")
        buf = backends.get("opencl-buffer")
        img = backends.get("opencl-image")
        if not ref or not buf:
            continue
        img_ms = f"{img['real_time']:.3f}" if img else "n/a"
        ratio = f"{img['real_time'] / buf['real_time']:.2f}x" if img else "n/a"
        print(f"| {model} | {int(ref['points'])} | {int(ref['fields'])} | "
              f"{ref['real_time']:.3f} | {buf['real_time']:.3f} | {img_ms} | "
              f"{ref['real_time'] / buf['real_time']:.2f}x | {ratio} |")
    print()


def field_compose_table(data):
    # FieldCompose/<op>/<backend>/<model>/real_time, against
    # FieldEval/<backend>/<model>/real_time (the union) of the same run.
    union = group_runs(data, "FieldEval", 3, lambda p: (p[2], p[1]))
    runs = group_runs(data, "FieldCompose", 4, lambda p: ((p[3], p[1]), p[2]))
    if not runs:
        return
    print("| model | operator | pairs | fields per point | reference ms "
          "| OpenCL buffer ms | OpenCL image ms | reference / union "
          "| buffer / union | image / union |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for (model, op), backends in runs.items():
        ref = backends.get("reference")
        if not ref:
            continue
        cells, ratios = [], []
        for backend in ("reference", "opencl-buffer", "opencl-image"):
            run = backends.get(backend)
            base = union.get(model, {}).get(backend)
            cells.append(f"{run['real_time']:.3f}" if run else "n/a")
            ratios.append(f"{run['real_time'] / base['real_time']:.2f}x"
                          if run and base else "n/a")
        print(f"| {model} | {op} | {int(ref['pairs'])} | "
              f"{ref['fields_per_point']:.1f} of {int(ref['fields'])} | "
              + " | ".join(cells) + " | " + " | ".join(ratios) + " |")
    print()


def operator_table_table(data):
    # OperatorTable/<op>/iterations:<n>/real_time
    rows = [b for b in data["benchmarks"]
            if b["name"].startswith("OperatorTable/")
            and not b.get("error_occurred")]
    if not rows:
        return
    print("| operator table | MiB | bake ms | threads |")
    print("|---|---:|---:|---|")
    for b in rows:
        print(f"| {b['name'].split('/')[1]} | {b['table_MiB']:.0f} | "
              f"{b['real_time']:.0f} | {b.get('label', '')} |")
    print()


def implicit_table(data):
    # Implicit/<model>/<backend>[/min_time:<s>]/real_time, backend one of
    # opencl (ImplicitSkinner), dqs (ClSkinning, same device), reference
    # (CpuImplicitSkinner).
    runs = group_runs(data, "Implicit", 3, lambda p: (p[1], p[2]))
    if not runs:
        return
    stages = ("skinning", "projection", "relaxation", "smoothing", "normals",
              "upload", "readback")
    print("| model | vertices | tracked | implicit ms/frame | DQS ms/frame "
          "| implicit / DQS | implicit fps | DQS fps | "
          + " | ".join(f"{s} ms" for s in stages)
          + " | contact vertices | reference ms/frame "
          "| OpenCL speed-up |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|"
          + "---:|" * len(stages) + "---:|---:|---:|")
    for model, backends in runs.items():
        cl = backends.get("opencl")
        if not cl:
            continue
        dqs, ref = backends.get("dqs"), backends.get("reference")
        cl_ms = cl["real_time"]
        dqs_ms = f"{dqs['real_time']:.3f}" if dqs else "n/a"
        ratio = f"{cl_ms / dqs['real_time']:.1f}x" if dqs else "n/a"
        dqs_fps = f"{dqs['fps']:.0f}" if dqs else "n/a"
        ref_ms = f"{ref['real_time']:.3f}" if ref else "n/a"
        speedup = f"{ref['real_time'] / cl_ms:.2f}x" if ref else "n/a"
        print(f"| {model} | {int(cl['vertices'])} | {int(cl['tracked'])} | "
              f"{cl_ms:.3f} | {dqs_ms} | "
              f"{ratio} | {cl['fps']:.1f} | {dqs_fps} | "
              + " | ".join(f"{cl[s + '_ms']:.3f}" for s in stages)
              + f" | {cl['contact']:.0f} | {ref_ms} | {speedup} |")
    print()


def main(path):
    with open(path) as f:
        data = json.load(f)
    ctx = data.get("context", {})
    device = next((b.get("label", "") for b in data["benchmarks"]
                   if "/opencl" in b["name"]), "")
    print(f"Run of {ctx.get('date', '?')} on {ctx.get('num_cpus', '?')} CPUs; "
          f"OpenCL device: {device or 'none'}.\n")
    frame_table(data)
    field_build_table(data)
    field_eval_table(data)
    field_compose_table(data)
    operator_table_table(data)
    implicit_table(data)


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: benchmarks_to_markdown.py BENCH.json")
    main(sys.argv[1])
