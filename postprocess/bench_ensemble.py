#!/usr/bin/env python3
"""Ensemble benchmark (make bench): throughput of eme_ensemble on 1 and 2 ranks.

Two studies of the paper scene (EME_theta), each run from an empty output directory:
  - index-only: inputs/bench_ensemble.nml, 2000 cases, one index row per case and no files;
  - with files: the same scene, 200 cases (a sweep of theta(2)), a case file each.
Repeat by repeat, the four runs (each study on 1 and on 2 ranks) alternate, so that the ratios
compare runs made seconds apart; medians over `--repeats` are reported:
  - study time (the driver's last line: scheduling included, MPI and PETSc start-up not) and the
    whole mpirun command, as cases per second;
  - overhead per case: everything the ranks spend outside the cases' time loops (model and
    solver set-up, files, the index, scheduling, waiting), (P T_P - sum of loop times) / sum of
    loop times, with the loop times from the index's solve_time_seconds;
  - parallel efficiency T_1 / (2 T_2), the median of the per-repeat ratios.
The last line is machine-readable.
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
INDEX_ONLY_STUDY = ROOT / "inputs" / "bench_ensemble.nml"
OUTPUT = ROOT / "results" / "bench_ensemble"
FILES_OUTPUT = ROOT / "results" / "bench_ensemble_files"
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


def files_study():
    """The study with case files: 200 cases of theta(2), written next to its output."""
    FILES_OUTPUT.parent.mkdir(parents=True, exist_ok=True)
    path = FILES_OUTPUT.parent / "bench_ensemble_files.nml"
    values = ", ".join(f"{340 + 0.1 * i:.1f}" for i in range(200))
    path.write_text(f"&study base = 'inputs/paper_fig4_eme_theta.nml', output_dir = '{FILES_OUTPUT}' /\n"
                    f"&sweep field = 'theta(2)', values = {values} /\n")
    return path


def run_once(study, output, ranks):
    """One study from scratch: (study seconds, command seconds, sum of loop seconds, cases)."""
    shutil.rmtree(output, ignore_errors=True)
    start = time.perf_counter()
    result = subprocess.run([*MPIRUN, "-n", str(ranks), str(ROOT / "build" / "bin" / "eme_ensemble"), str(study)],
                            capture_output=True, text=True, cwd=ROOT)
    command = time.perf_counter() - start
    if result.returncode != 0:
        raise SystemExit(f"eme_ensemble failed:\n{result.stdout}\n{result.stderr}")
    seconds = float(re.search(r"wall time\s+([0-9.]+) s", result.stdout).group(1))
    with h5py.File(output / "index.h5", "r") as f:
        cases = f["cases"][:]
    if not all(status == b"complete" for status in cases["status"]):
        raise SystemExit("eme_ensemble: not every benchmark case completed")
    return seconds, command, float(cases["solve_time_seconds"].sum()), len(cases)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=3, help="runs of each study on each rank count (default 3)")
    args = parser.parse_args(argv)
    print(f"machine: {machine()}")
    studies = {"index-only": (INDEX_ONLY_STUDY, OUTPUT), "with files": (files_study(), FILES_OUTPUT)}
    runs = {(name, ranks): [] for name in studies for ranks in (1, 2)}
    for _ in range(args.repeats):
        for name, (study, output) in studies.items():
            for ranks in (1, 2):
                runs[name, ranks].append(run_once(study, output, ranks))
    summary = {}
    for name in studies:
        for ranks in (1, 2):
            measured = runs[name, ranks]
            cases = measured[0][3]
            study = statistics.median(r[0] for r in measured)
            command = statistics.median(r[1] for r in measured)
            overhead = statistics.median((ranks * r[0] - r[2]) / r[2] for r in measured)
            per_case = statistics.median((ranks * r[0] - r[2]) / r[3] for r in measured)
            loop = statistics.median(r[2] / r[3] for r in measured)
            summary[name, ranks] = overhead
            print(f"{name}, {ranks} rank(s): {cases} cases, median of {args.repeats}: study {study:.3f} s = "
                  f"{cases / study:.1f} cases/s (whole mpirun {command:.3f} s); time loop {1e3 * loop:.2f} ms per "
                  f"case; overhead per case {1e3 * per_case:.3f} ms = {100 * overhead:.1f} % of its loop")
        efficiency = statistics.median(one[0] / (2 * two[0]) for one, two in zip(runs[name, 1], runs[name, 2]))
        summary[name, "efficiency"] = efficiency
        print(f"{name}: parallel efficiency at 2 ranks {efficiency:.3f}")
    print(f"ensemble_overhead_index_only={100 * summary['index-only', 1]:.2f}% "
          f"efficiency_2_ranks={summary['index-only', 'efficiency']:.3f} "
          f"ensemble_overhead_with_files={100 * summary['with files', 1]:.2f}%")
    return 0


if __name__ == "__main__":
    sys.exit(main())
