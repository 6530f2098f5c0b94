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
  - parallel efficiency T_1 / (2 T_2), the median of the per-repeat ratios;
  - the machine's own ceiling for it: the index-only study split in two halves, run as two
    independent single-rank studies at the same time (no scheduling between them), T_1 / (2 T_pair).
    On a machine whose cores slow each other down, or that other work shares, this ceiling is
    below 1, and T_pair / T_2 is what the scheduler achieves of it;
  - the cost of a case file: the 200 cases with files against the same 200 cases index-only, on
    one rank, run right after each other, (T_files - T_index) / 200, set beside the case's own
    compute time (its time loop, the index's solve_time_seconds).
Cases per second of each study on 1 and 2 ranks and the file cost are printed on lines of their
own; then the machine's load (machine_load.py: the 1-minute load average before and after the
runs, the cores, a warning when it was busy); the last line is machine-readable and ends with the
load.
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

import machine_load

ROOT = Path(__file__).resolve().parent.parent
INDEX_ONLY_STUDY = ROOT / "inputs" / "bench_ensemble.nml"
OUTPUT = ROOT / "results" / "bench_ensemble"
FILES_OUTPUT = ROOT / "results" / "bench_ensemble_files"
SAME_CASES_OUTPUT = ROOT / "results" / "bench_ensemble_files_index_only"
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


def files_study(output=FILES_OUTPUT, index_only=False):
    """The study with case files: 200 cases of theta(2), written next to its output (or the
    same cases index-only)."""
    output.parent.mkdir(parents=True, exist_ok=True)
    path = output.parent / f"{output.name}.nml"
    values = ", ".join(f"{340 + 0.1 * i:.1f}" for i in range(200))
    only = ", index_only = .true." if index_only else ""
    path.write_text(f"&study base = '{ROOT / 'inputs' / 'paper_fig4_eme_theta.nml'}', output_dir = '{output}'{only} /\n"
                    f"&sweep field = 'theta(2)', values = {values} /\n")
    return path


def half_studies():
    """The index-only study split in two halves of theta(1) (1000 cases each)."""
    text = INDEX_ONLY_STUDY.read_text()
    sweep = re.search(r"&sweep field = 'theta\(1\)',\s*values = ([^/]*)/", text)
    values = [v.strip() for v in sweep.group(1).split(",")]
    halves = []
    for k, part in enumerate((values[:len(values) // 2], values[len(values) // 2:])):
        output = ROOT / "results" / f"bench_ensemble_half{k + 1}"
        path = output.parent / f"bench_ensemble_half{k + 1}.nml"
        half = text[:sweep.start()] + f"&sweep field = 'theta(1)', values = {', '.join(part)} /" + text[sweep.end():]
        half = half.replace("output_dir = 'results/bench_ensemble'", f"output_dir = '{output}'")
        path.write_text(half.replace("base = 'paper_fig4_eme_theta.nml'",
                                     f"base = '{ROOT / 'inputs' / 'paper_fig4_eme_theta.nml'}'"))
        halves.append((path, output))
    return halves


def run_pair(halves):
    """Both halves at once, each a single-rank study: the seconds until both have ended."""
    processes = []
    for study, output in halves:
        shutil.rmtree(output, ignore_errors=True)
        # Two mpirun jobs would bind both ranks to the first core: no binding.
        processes.append(subprocess.Popen([*MPIRUN, "--bind-to", "none", "-n", "1", str(ROOT / "build" / "bin" / "eme_ensemble"),
                                           str(study)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                          cwd=ROOT))
    seconds = []
    for process in processes:
        out, err = process.communicate()
        if process.returncode != 0:
            raise SystemExit(f"eme_ensemble failed:\n{out}\n{err}")
        seconds.append(float(re.search(r"wall time\s+([0-9.]+) s", out).group(1)))
    return max(seconds)


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
    halves, pairs = half_studies(), []
    same_cases = files_study(SAME_CASES_OUTPUT, index_only=True)
    file_costs, case_times = [], []
    # Two ranks at most run at once (the 2-rank studies, the two halves).
    with machine_load.measured(own=2) as load:
        repeat_runs(args.repeats, studies, runs, halves, pairs, same_cases, file_costs, case_times)
    report(args.repeats, studies, runs, pairs, file_costs, case_times, load)
    return 0


def repeat_runs(repeats, studies, runs, halves, pairs, same_cases, file_costs, case_times):
    """The alternating runs, repeat by repeat, their figures appended to the lists given."""
    for _ in range(repeats):
        for name, (study, output) in studies.items():
            for ranks in (1, 2):
                runs[name, ranks].append(run_once(study, output, ranks))
        without = run_once(same_cases, SAME_CASES_OUTPUT, 1)
        with_files = runs["with files", 1][-1]
        file_costs.append((with_files[0] - without[0]) / with_files[3])
        case_times.append(without[2] / without[3])
        pairs.append(run_pair(halves))


def report(repeats, studies, runs, pairs, file_costs, case_times, load):
    """Prints the medians, the ratios and the machine's load."""
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
            print(f"{name}, {ranks} rank(s): {cases} cases, median of {repeats}: study {study:.3f} s = "
                  f"{cases / study:.1f} cases/s (whole mpirun {command:.3f} s); time loop {1e3 * loop:.2f} ms per "
                  f"case; overhead per case {1e3 * per_case:.3f} ms = {100 * overhead:.1f} % of its loop")
        efficiency = statistics.median(one[0] / (2 * two[0]) for one, two in zip(runs[name, 1], runs[name, 2]))
        summary[name, "efficiency"] = efficiency
        print(f"{name}: parallel efficiency at 2 ranks {efficiency:.3f}")
        if name == "index-only":
            ceiling = statistics.median(one[0] / (2 * pair) for one, pair in zip(runs[name, 1], pairs))
            achieved = statistics.median(pair / two[0] for pair, two in zip(pairs, runs[name, 2]))
            summary["ceiling"], summary["achieved"] = ceiling, achieved
            print(f"{name}: two independent single-rank halves at once: {statistics.median(pairs):.3f} s, the "
                  f"machine's ceiling for the efficiency {ceiling:.3f}; 2 ranks reach {achieved:.3f} of it")
    for name in studies:
        for ranks in (1, 2):
            measured = runs[name, ranks]
            print(f"cases/s, {name}, {ranks} rank{'s' if ranks > 1 else ''}: "
                  f"{statistics.median(r[3] / r[0] for r in measured):.1f} (median of {repeats})")
    file_cost, case_time = statistics.median(file_costs), statistics.median(case_times)
    print(f"file cost per case: {1e3 * file_cost:.3f} ms (200 cases with files minus the same cases index-only, "
          f"1 rank, median of {repeats})")
    print(f"case compute time: {1e3 * case_time:.3f} ms (time loop, solve_time_seconds; file cost / case time "
          f"{file_cost / case_time:.2f})")
    print(load.text())
    print(f"efficiency at 2 ranks against the machine's ceiling: index-only {summary['achieved']:.3f}, with files "
          f"{summary['with files', 'efficiency'] / summary['ceiling']:.3f}")
    print(f"ensemble_overhead_index_only={100 * summary['index-only', 1]:.2f}% "
          f"efficiency_2_ranks={summary['index-only', 'efficiency']:.3f} machine_ceiling={summary['ceiling']:.3f} "
          f"ensemble_overhead_with_files={100 * summary['with files', 1]:.2f}% "
          f"file_cost_per_case_ms={1e3 * file_cost:.3f} case_time_ms={1e3 * case_time:.3f} "
          f"{load.fields()}")
    if load.busy:
        print(f"bench_ensemble.py: {load.warning()}", file=sys.stderr)


if __name__ == "__main__":
    sys.exit(main())
