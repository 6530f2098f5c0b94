#!/usr/bin/env python3
"""Ensemble benchmark (make bench): throughput of eme_ensemble on 1 and 2 ranks.

Runs the study inputs/bench_ensemble.nml (200 paper-scene cases) `--repeats` times per rank
count, each time from an empty output directory, and reports medians:
  - throughput in cases per second, from the study's own elapsed time (the driver's last line,
    which leaves out MPI and PETSc start-up) and from the whole mpirun command;
  - parallel efficiency T_1 / (P T_P);
  - overhead per case: everything a rank spends outside the cases' time loops (file set-up and
    closing, solver set-up, scheduling, waiting), (P T_P - sum of loop times) / sum of loop
    times, from the index's solve_time_seconds.
"""
import argparse
import os
import platform
import re
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

import h5py

ROOT = Path(__file__).resolve().parent.parent
STUDY = ROOT / "inputs" / "bench_ensemble.nml"
OUTPUT = ROOT / "results" / "bench_ensemble"
MPIRUN = ["mpirun", "--allow-run-as-root", "--oversubscribe"]


def machine():
    """CPU model, core count and OS, for the report."""
    model = "unknown CPU"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{model}, {os.cpu_count()} cores, {platform.system()} {platform.release()}"


def run_once(ranks):
    """One study from scratch; returns (study seconds, command seconds, sum of loop seconds)."""
    shutil.rmtree(OUTPUT, ignore_errors=True)
    start = time.perf_counter()
    result = subprocess.run([*MPIRUN, "-n", str(ranks), str(ROOT / "build" / "bin" / "eme_ensemble"), str(STUDY)],
                            capture_output=True, text=True, cwd=ROOT)
    command = time.perf_counter() - start
    if result.returncode != 0:
        raise SystemExit(f"eme_ensemble failed:\n{result.stdout}\n{result.stderr}")
    study = float(re.search(r"wall time\s+([0-9.]+) s", result.stdout).group(1))
    with h5py.File(OUTPUT / "index.h5", "r") as f:
        cases = f["cases"][:]
    if not all(status == b"complete" for status in cases["status"]):
        raise SystemExit("eme_ensemble: not every benchmark case completed")
    return study, command, float(cases["solve_time_seconds"].sum()), len(cases)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=3, help="runs per rank count (default 3)")
    args = parser.parse_args(argv)
    print(f"machine: {machine()}")
    results = {}
    for ranks in (1, 2):
        runs = [run_once(ranks) for _ in range(args.repeats)]
        n_cases = runs[0][3]
        study = statistics.median(r[0] for r in runs)
        command = statistics.median(r[1] for r in runs)
        loops = statistics.median(r[2] for r in runs)
        overhead = (ranks * study - loops) / loops
        results[ranks] = study
        print(f"{ranks} rank(s): {n_cases} cases, median of {args.repeats}: study {study:.3f} s = "
              f"{n_cases / study:.1f} cases/s (whole mpirun {command:.3f} s = {n_cases / command:.1f} cases/s); "
              f"time loops {loops:.3f} s, overhead per case {100 * overhead:.1f} % of its loop time "
              f"({1e3 * (ranks * study - loops) / n_cases:.2f} ms)")
    efficiency = results[1] / (2 * results[2])
    print(f"parallel efficiency at 2 ranks: {efficiency:.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
