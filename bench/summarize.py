#!/usr/bin/env python3
"""Summarize an engine_bench JSON file (--benchmark_out=FILE --benchmark_out_format=json):
one line per benchmark with the median (or the single run) real and CPU time in ms, plus
CHOLMOD / SimplicialLLT ratios from the same file. Usage: bench/summarize.py run.json"""
import json
import re
import sys


def main(path):
    data = json.load(open(path))
    rows = {}
    for b in data["benchmarks"]:
        if b.get("run_type") == "aggregate" and b.get("aggregate_name") != "median":
            continue
        name = b.get("run_name", b["name"])
        name = re.sub(r"/(iterations:\d+|repeats:\d+|real_time|min_time:[\d.]+)", "", name)
        scale = {"ns": 1e-6, "us": 1e-3, "ms": 1.0, "s": 1e3}[b.get("time_unit", "ns")]
        counters = {k: v for k, v in b.items() if k not in (
            "name", "run_name", "run_type", "repetitions", "repetition_index", "threads",
            "iterations", "real_time", "cpu_time", "time_unit", "family_index",
            "per_family_instance_index", "aggregate_name", "aggregate_unit")}
        rows[name] = (b["real_time"] * scale, b["cpu_time"] * scale, b.get("iterations"), counters)
    ctx = data["context"]
    print(f"# {ctx.get('date')}  load_avg={ctx.get('load_avg')}  cpus={ctx.get('num_cpus')}")
    print(f"{'benchmark':58s} {'real ms':>10s} {'cpu ms':>10s}")
    for name, (real, cpu, _, counters) in rows.items():
        extra = " ".join(f"{k}={v:.4g}" for k, v in counters.items()
                         if isinstance(v, (int, float)) and k not in ("n", "nF"))
        print(f"{name:58s} {real:10.3f} {cpu:10.3f}  {extra}")
    print("\n# CHOLMOD supernodal (METIS) / SimplicialLLT (AMD), real time, same run")
    for name, (real, _, _, _) in rows.items():
        if "/simplicial/" not in name:
            continue
        other = name.replace("/simplicial/", "/cholmod/")
        if other in rows:
            print(f"{other.replace('/cholmod', ''):58s} {rows[other][0]:10.3f} / {real:10.3f}"
                  f" = {rows[other][0] / real:5.2f}")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "bench-results.json")
