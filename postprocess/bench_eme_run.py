#!/usr/bin/env python3
"""What the program a user runs costs per step against the benchmarked step (make bench).

eme_run integrates the paper scene with EME_theta over 200 s (1334 steps of 0.15 s, the file
written at the end); its cost per step is the file's solve_time_seconds (the time loop, with the
per-step energy, entropy and rows) over its steps. eme_bench times the same scheme's stepping
loop alone ("EME_temperature", through SNES). The two alternate, REPEATS times, in this one
script, so that the shared machine's drifts reach both; printed are the medians and the median of
the per-pair ratios, last as the line `eme_run_over_bench=<ratio>`.
"""
import argparse
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


def eme_run_us_per_step(binary, folder):
    """us per step of one eme_run of the scene."""
    output = folder / "scene.h5"
    namelist = folder / "scene.nml"
    namelist.write_text(SCENE.format(file=output))
    subprocess.run([str(binary), str(namelist)], check=True, capture_output=True)
    with h5py.File(output, "r") as f:
        return 1e6 * float(f.attrs["solve_time_seconds"]) / int(f.attrs["steps_completed"])


def bench_us_per_step(binary, repeats):
    """eme_bench's SNES us per step of EME_temperature (its table's first number)."""
    result = subprocess.run([str(binary), str(repeats)], check=True, capture_output=True, text=True)
    for line in result.stdout.splitlines():
        words = line.split()
        if words and words[0] == "EME_temperature":
            return float(words[1])
    raise RuntimeError("eme_bench printed no EME_temperature row:\n" + result.stdout)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--bin", default=str(ROOT / "build" / "bin"), help="folder of eme_run and eme_bench")
    parser.add_argument("--repeats", type=int, default=7, help="alternating pairs (default 7)")
    args = parser.parse_args()
    bin_dir = Path(args.bin)
    runs, benches, ratios = [], [], []
    with tempfile.TemporaryDirectory() as scratch:
        for _ in range(args.repeats):
            run = eme_run_us_per_step(bin_dir / "eme_run", Path(scratch))
            bench = bench_us_per_step(bin_dir / "eme_bench", 3)
            runs.append(run)
            benches.append(bench)
            ratios.append(run / bench)
    print(f"eme_run on the paper scene (EME_theta, 1334 steps): {statistics.median(runs):.2f} us/step; "
          f"eme_bench EME_temperature: {statistics.median(benches):.2f} us/step "
          f"(medians of {args.repeats} alternating pairs)")
    print(f"eme_run_over_bench={statistics.median(ratios):.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
