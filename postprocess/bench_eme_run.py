#!/usr/bin/env python3
"""The speed ratios of issue 22, each the median of alternating repeats in this one script (make bench).

eme_run integrates the paper scene with EME_theta over 200 s (1334 steps of 0.15 s, the file
written at the end); its cost per step is the file's solve_time_seconds (the time loop, with the
per-step energy, entropy and rows) over its steps, the median of 3 runs. eme_bench (3 repeats
per call) times the same scheme's stepping loop alone ("EME_temperature", through SNES), the hand-written Newton floor on
the same kernel, and SUNDIALS CVODE-BDF's internal step on the same scene. The two programs
alternate, REPEATS times, so that the shared machine's drifts reach both; printed are the medians
of the per-pair ratios, one per line with its target:
  snes_over_floor              eme_bench EME_theta / the floor                       (target 1.3)
  eme_over_cvode               eme_bench EME_theta / CVODE-BDF per internal step     (target 1.5)
  eme_run_over_cvode           eme_run per step / CVODE-BDF per internal step        (target 1.8)
  eme_run_over_bench           eme_run per step / eme_bench EME_theta                (target 1.15)
"""
import argparse
import re
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import h5py

ROOT = Path(__file__).resolve().parent.parent
SCENE = """&integrator scheme = 'eme', thermo_variable = 'temperature', dt = 0.15, t_end = 200.0 /
&output file = '{file}', overwrite = .true. /
"""


def eme_run_us_per_step(binary, folder, runs=3):
    """us per step of eme_run on the scene: the median of `runs` runs, as eme_bench 3 reports the
    median of its 3 repeats (one 12 ms run alone catches the shared machine's hiccups)."""
    output = folder / "scene.h5"
    namelist = folder / "scene.nml"
    namelist.write_text(SCENE.format(file=output))
    times = []
    for _ in range(runs):
        subprocess.run([str(binary), str(namelist)], check=True, capture_output=True)
        with h5py.File(output, "r") as f:
            times.append(1e6 * float(f.attrs["solve_time_seconds"]) / int(f.attrs["steps_completed"]))
    return statistics.median(times)


TARGETS = {"snes_over_floor": 1.3, "eme_over_cvode": 1.5, "eme_run_over_cvode": 1.8, "eme_run_over_bench": 1.15}


def bench_figures(binary, repeats):
    """From one eme_bench: EME_temperature's SNES and floor us per step, CVODE-BDF's us per internal step."""
    result = subprocess.run([str(binary), str(repeats)], check=True, capture_output=True, text=True)
    snes = floor = cvode = None
    for line in result.stdout.splitlines():
        row = re.match(r"EME_temperature\s+([0-9.]+)\s+([0-9.]+)", line)
        if row:
            snes, floor = float(row.group(1)), float(row.group(2))
        elif line.startswith("cvode_bdf_temperature"):
            cvode = float(re.search(r"([0-9.]+) us each", line).group(1))
    if None in (snes, floor, cvode):
        raise RuntimeError("eme_bench printed no EME_temperature or cvode_bdf_temperature row:\n" + result.stdout)
    return snes, floor, cvode


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--bin", default=str(ROOT / "build" / "bin"), help="folder of eme_run and eme_bench")
    parser.add_argument("--repeats", type=int, default=7, help="alternating pairs (default 7)")
    args = parser.parse_args()
    bin_dir = Path(args.bin)
    runs, benches, ratios = [], [], {name: [] for name in TARGETS}
    with tempfile.TemporaryDirectory() as scratch:
        for _ in range(args.repeats):
            run = eme_run_us_per_step(bin_dir / "eme_run", Path(scratch))
            snes, floor, cvode = bench_figures(bin_dir / "eme_bench", 3)
            runs.append(run)
            benches.append(snes)
            ratios["snes_over_floor"].append(snes / floor)
            ratios["eme_over_cvode"].append(snes / cvode)
            ratios["eme_run_over_cvode"].append(run / cvode)
            ratios["eme_run_over_bench"].append(run / snes)
    print(f"eme_run on the paper scene (EME_theta, 1334 steps): {statistics.median(runs):.2f} us/step; "
          f"eme_bench EME_temperature: {statistics.median(benches):.2f} us/step "
          f"(medians of {args.repeats} alternating pairs)")
    for name, target in TARGETS.items():
        value = statistics.median(ratios[name])
        verdict = "met" if value <= target else f"missed by {100 * (value / target - 1):.0f} %"
        print(f"{name}={value:.3f}  (target {target}: {verdict})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
