#!/usr/bin/env python3
"""Turns isk_bench's JSON output into the tables of BENCHMARKS.md.

    build/bench/isk_bench --benchmark_out=bench.json --benchmark_out_format=json
    python3 bench/benchmarks_to_markdown.py bench.json > tables.md

Each row pairs the OpenCL and CPU-reference runs of one model and method from
the same run, so the speed-up is a ratio measured in one process.
"""
import json
import sys


def main(path):
    with open(path) as f:
        data = json.load(f)
    runs = {}
    for b in data["benchmarks"]:
        # Frame/<backend>/<model>/<method>/real_time
        parts = b["name"].split("/")
        if len(parts) < 4 or parts[0] != "Frame":
            continue
        backend, model, method = parts[1], parts[2], parts[3]
        runs.setdefault((model, method), {})[backend] = b
    ctx = data.get("context", {})
    device = next((b.get("label", "") for b in data["benchmarks"]
                   if "/opencl/" in b["name"]), "")
    print(f"Run of {ctx.get('date', '?')} on {ctx.get('num_cpus', '?')} CPUs; "
          f"OpenCL device: {device or 'none'}.\n")
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


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: benchmarks_to_markdown.py BENCH.json")
    main(sys.argv[1])
