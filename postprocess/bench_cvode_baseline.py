#!/usr/bin/env python3
"""Issue 34's ratios against CVODE-BDF on the same model (make bench): instructions per step, and
a whole eme_run against a whole C program with CVODE alone.

Instructions (valgrind's callgrind; machine-independent, so they do not move with the load) per
step at the paper scene's dt, each the difference of two run lengths of the paper scene (t_end =
10 s and 20 s: what the processes spend once, start-up, set-up and the end, cancels):
  - EME_theta's step: the stepper's `advance` in eme_run (the kernel through SNES, with the
    predictor and the retry strategies), per step;
  - eme_run's whole step: the whole eme_run process per step (the step, the energy, entropy and
    temperatures of the new state, the rows and the file), with its writes at the end as in a
    run shorter than a second (EME_WRITE_EVERY_ROWS: under callgrind's slowdown the clock would
    otherwise write the file every second);
  - CVODE-BDF's internal step: the whole build/bin/cvode_baseline process (drivers/cvode_baseline.c:
    SUNDIALS alone, the field in C) per internal step, and, for comparison, `CVode` in eme_run's
    cvode_bdf (the same method, the field through the Fortran model) per internal step.
Printed on their own lines with their targets (bench_eme_run.py's format):
  eme_over_cvode_instructions      EME_theta's step / cvode_baseline's internal step     (target 1.5)
  eme_run_over_cvode_instructions  eme_run's whole step / cvode_baseline's internal step (target 2.5)
with the instructions before `main` of eme_run's paper scene (the dynamic loader and the
libraries' constructors) and their share of the process.

Whole run: the process wall time of eme_run on the paper scene (inputs/paper_fig4_eme_theta.nml,
its file in a scratch folder) and of cvode_baseline (to t = 20 s), alternating, the order
flipped every repeat; the medians and the median of the per-pair ratios (their CPU times beside):
  whole_run_over_cvode_baseline    eme_run's process / cvode_baseline's process           (target 2.5)

Each part ends with the machine's load around it (machine_load.py). A program that fails, or a
missing valgrind, ends the script with the message and exit status 1.
"""
import os
import re
import resource
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

import h5py

import machine_load
from bench_eme_run import ProgramFailed, bench_main, run_program, target_line

ROOT = Path(__file__).resolve().parent.parent
PAPER_SCENE = ROOT / "inputs" / "paper_fig4_eme_theta.nml"
SHORT, LONG = 10.0, 20.0          # the two run lengths, s
TARGETS = {"eme_over_cvode_instructions": 1.5, "eme_run_over_cvode_instructions": 2.5,
           "whole_run_over_cvode_baseline": 2.5}
# The file is written once at the end, as when the run takes less than a second (crash_safe_file).
NO_CLOCKED_WRITES = dict(os.environ, EME_WRITE_EVERY_ROWS="1000000000")


def scene_text(file, t_end=None, scheme=None):
    """inputs/paper_fig4_eme_theta.nml with its file in `file`, optionally another t_end or scheme
    (cvode_bdf at its default tolerance, 1e-10)."""
    text = PAPER_SCENE.read_text()
    for pattern, value in ((r"file\s*=\s*'[^']*'", f"file = '{file}', overwrite = .true."),
                           (r"t_end\s*=\s*[0-9.eEd+-]+", t_end is not None and f"t_end = {t_end}"),
                           (r"scheme\s*=\s*'[^']*'", scheme is not None and f"scheme = '{scheme}'")):
        if value:
            text, found = re.subn(pattern, value, text)
            if found != 1:
                raise ProgramFailed(f"{PAPER_SCENE} has {found} fields matching {pattern}, not one")
    return text


def callgrind(command, folder, name, functions=()):
    """Runs command under callgrind: its total instructions and the inclusive instructions of each
    function in `functions` (a function callgrind_annotate names `file:function`), and its stdout."""
    profile = folder / f"{name}.callgrind"
    stdout = run_program(["valgrind", "--tool=callgrind", f"--callgrind-out-file={profile}", *command],
                         env=NO_CLOCKED_WRITES)
    annotated = run_program(["callgrind_annotate", "--inclusive=yes", "--threshold=100", str(profile)])
    total = re.search(r"^\s*([0-9,]+)\s.*PROGRAM TOTALS", annotated, re.MULTILINE)
    if not total:
        raise ProgramFailed(f"callgrind_annotate printed no PROGRAM TOTALS for {name}")
    counts = {"total": int(total.group(1).replace(",", ""))}
    for function in functions:
        found = re.search(rf"^\s*([0-9,]+)\s.*:{re.escape(function)}(@\S*)? \[", annotated, re.MULTILINE)
        if not found:
            raise ProgramFailed(f"callgrind of {name} shows no function {function}")
        counts[function] = int(found.group(1).replace(",", ""))
    return counts, stdout


def eme_run_counts(bin_dir, folder, scheme, t_end, functions):
    """callgrind of eme_run on the paper scene to t_end (scheme: EME_theta's, or another); the
    counts and the steps the file records (CVODE: its internal steps)."""
    name = f"{scheme or 'eme'}_{t_end:g}"
    namelist = folder / f"{name}.nml"
    output = folder / f"{name}.h5"
    namelist.write_text(scene_text(output, t_end, scheme))
    counts, _ = callgrind([bin_dir / "eme_run", namelist], folder, name, functions)
    with h5py.File(output, "r") as f:
        counts["steps"] = int(f["snes_solves"][()].sum()) if scheme else int(f.attrs["steps_completed"])
    return counts


def baseline_counts(bin_dir, folder, t_end):
    """callgrind of cvode_baseline to t_end: its counts and CVODE's internal steps."""
    counts, stdout = callgrind([bin_dir / "cvode_baseline", "--t-end", t_end], folder, f"cvode_baseline_{t_end:g}")
    counts["steps"] = int(re.search(r"^steps=(\d+)", stdout, re.MULTILINE).group(1))
    return counts


def per_step(short, long, key="total"):
    """Instructions per step between two run lengths: the difference over the steps' difference."""
    return (long[key] - short[key]) / (long["steps"] - short["steps"])


def instructions(bin_dir, folder):
    """The instruction counts' part; prints its lines."""
    for tool in ("valgrind", "callgrind_annotate"):
        if shutil.which(tool) is None:
            raise ProgramFailed(f"{tool} is not installed: make bench installs it (Debian: apt-get install valgrind)")
    eme_step, cvode_step, start = "__discrete_gradient_stepper_MOD_advance", "CVode", "__libc_start_main"
    with machine_load.measured(own=1) as load:
        eme = [eme_run_counts(bin_dir, folder, None, t, (eme_step, start)) for t in (SHORT, LONG)]
        cvode = [eme_run_counts(bin_dir, folder, "cvode_bdf", t, (cvode_step,)) for t in (SHORT, LONG)]
        baseline = [baseline_counts(bin_dir, folder, t) for t in (SHORT, LONG)]
    step, whole, c_step = per_step(*eme, eme_step), per_step(*eme), per_step(*baseline)
    cvode_in_eme_run, cvode_eme_run_whole = per_step(*cvode, cvode_step), per_step(*cvode)
    paper = eme[1]
    before_main = paper["total"] - paper[start]
    print(f"instructions per step (callgrind; the paper scene at dt = 0.15 s, runs to t = {LONG:g} s minus runs "
          f"to {SHORT:g} s: {eme[1]['steps'] - eme[0]['steps']} EME_theta steps, "
          f"{baseline[1]['steps'] - baseline[0]['steps']} CVODE-BDF internal steps of cvode_baseline):")
    print(f"  EME_theta's step (eme_run, the stepper's advance: the kernel through SNES): {step:,.0f}")
    print(f"  eme_run's whole step (the process: the step, its rows and records, the file): {whole:,.0f}")
    print(f"  CVODE-BDF's internal step (cvode_baseline, C and SUNDIALS alone): {c_step:,.0f}")
    print(f"  CVODE-BDF's internal step in eme_run's cvode_bdf (CVode, the field through the Fortran model): "
          f"{cvode_in_eme_run:,.0f} ({cvode_eme_run_whole:,.0f} with the process's rows and records)")
    print(f"eme_step_instructions={step:.0f} eme_run_step_instructions={whole:.0f} "
          f"cvode_step_instructions={c_step:.0f} eme_run_cvode_step_instructions={cvode_in_eme_run:.0f}")
    print(target_line("eme_over_cvode_instructions", step / c_step, TARGETS["eme_over_cvode_instructions"]))
    print(target_line("eme_run_over_cvode_instructions", whole / c_step, TARGETS["eme_run_over_cvode_instructions"]))
    print(f"  against eme_run's cvode_bdf instead: EME_theta's step {step / cvode_in_eme_run:.3f}, eme_run's whole "
          f"step {whole / cvode_eme_run_whole:.3f}")
    print(f"before main (the dynamic loader and the libraries' constructors), eme_run's paper scene to "
          f"{LONG:g} s: {before_main / 1e6:.1f} M of {paper['total'] / 1e6:.1f} M instructions; its "
          f"{paper['steps']} steps {paper[eme_step] / 1e6:.1f} M")
    print(f"before_main_instructions={before_main} before_main_share={before_main / paper['total']:.3f} "
          f"before_main_over_steps={before_main / paper[eme_step]:.1f}")
    load.report("bench_cvode_baseline.py")


def wall_and_cpu(command, env=None):
    """The process's wall time and CPU time (user and system), s (ProgramFailed if it fails); in
    environment `env`, else this one's."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    run_program(command, env=env)
    elapsed = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return elapsed, after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime


def whole_runs(bin_dir, folder, repeats):
    """The whole-run part: eme_run's paper scene and cvode_baseline alternating; prints its lines."""
    namelist = folder / "paper_scene.nml"
    namelist.write_text(scene_text(folder / "paper_scene.h5"))
    programs = {"eme_run": [bin_dir / "eme_run", namelist], "cvode_baseline": [bin_dir / "cvode_baseline"]}
    times = {name: [] for name in programs}
    with machine_load.measured(own=1) as load:
        for repeat in range(repeats):
            for name in (list(programs) if repeat % 2 == 0 else reversed(list(programs))):
                times[name].append(wall_and_cpu(programs[name]))
    median = statistics.median
    walls, cpus = ({name: [t[k] for t in times[name]] for name in times} for k in (0, 1))
    ratio = median(run / c for run, c in zip(walls["eme_run"], walls["cvode_baseline"]))
    print(f"whole run (process wall, medians of {repeats} alternating pairs): eme_run on the paper scene "
          f"{1e3 * median(walls['eme_run']):.1f} ms, cvode_baseline to t = 20 s "
          f"{1e3 * median(walls['cvode_baseline']):.1f} ms; their CPU times {1e3 * median(cpus['eme_run']):.1f} and "
          f"{1e3 * median(cpus['cvode_baseline']):.1f} ms (ratio "
          f"{median(run / c for run, c in zip(cpus['eme_run'], cpus['cvode_baseline'])):.3f})")
    print(target_line("whole_run_over_cvode_baseline", ratio, TARGETS["whole_run_over_cvode_baseline"]))
    load.report("bench_cvode_baseline.py")


def measure(bin_dir, repeats):
    """Both parts, in a scratch folder of their own."""
    with tempfile.TemporaryDirectory(prefix="bench_cvode_baseline_") as scratch:
        instructions(bin_dir, Path(scratch))
        whole_runs(bin_dir, Path(scratch), repeats)
    return 0


def main(argv=None):
    return bench_main(argv, __doc__, "eme_run and cvode_baseline", 15, measure)


if __name__ == "__main__":
    sys.exit(main())
