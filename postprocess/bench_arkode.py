#!/usr/bin/env python3
"""Issue 42's work-precision target (make bench): relaxed_dp853's integration against ARKODE's
explicit Dormand-Prince 5(4) on the paper scene, in instructions at every error decade.

Both integrate the paper scene (Table 1, the initial state of docs/formulation.md section 1,
temperature variable) to t = 5 s, each at rtol = atol = TOL for every TOL of TOLERANCES:
  - relaxed_dp853: eme_run (dt = 0.15 s its first trial step); its work is the inclusive
    instructions of the relaxed stepper's `advance` (the steps, their relaxation, error estimate
    and control; not the rows and the file);
  - ARKODE DP5: build/bin/cvode_baseline --arkode-dp5 (drivers/cvode_baseline.c: ERKStep with the
    Dormand-Prince 5(4) table and the C field); its work is the inclusive instructions of
    `ERKStepEvolve`.
Instructions are valgrind's callgrind counts (machine-independent: they do not move with the load).
The error is issue 42's metric, max(|q, p, gamma - ref|, |theta - ref|/300 K) at t = 5 s, each
against a tight reference of its own code (relaxed_dp853 at 1e-13, DP5 at 1e-13, run without
callgrind); the two references' distance is printed too. The programs alternate, tolerance by
tolerance. At each error decade from 1e-4 to 1e-10 each code's instructions are interpolated
(log-log, between the two runs that bracket it) and the ratio printed on its own line with its
target (bench_eme_run.py's format):
  relaxed_dp853_over_dp5_at_1e-4 ... _at_1e-10   (target 1.0)
A decade a code's runs do not bracket is said so, with no ratio. Then the machine's load around it
(machine_load.py). A program that fails, or a missing valgrind, ends the script with the message
and exit status 1.
"""
import math
import re
import shutil
import sys
import tempfile
from pathlib import Path

import h5py
import numpy as np

import machine_load
from bench_cvode_baseline import callgrind
from bench_eme_run import ProgramFailed, bench_main, run_program, target_line

T_END = 5.0
TOLERANCES = [10.0 ** -k for k in range(4, 13)]
REFERENCE_TOLERANCE = 1e-13
DECADES = [10.0 ** -k for k in range(4, 11)]
TEMPERATURE_SCALE = 300.0          # K: the metric's temperature scale (issue 42)
EME_WORK, DP5_WORK = "__relaxed_stepper_MOD_advance", "ERKStepEvolve"

SCENE = """&integrator
  scheme = 'relaxed_dp853'
  thermo_variable = 'temperature'
  dt = 0.15
  t_end = {t_end}
  tolerance = {tolerance:.1e}
/
&output
  file = '{file}'
  overwrite = .true.
/
"""


def error(state, reference):
    """Issue 42's metric: max(|q, p, gamma - ref|, |theta - ref|/300 K)."""
    return max(np.abs(state[:13] - reference[:13]).max(), np.abs(state[13:] - reference[13:]).max() / TEMPERATURE_SCALE)


def eme_command(bin_dir, folder, tolerance):
    """eme_run's command for relaxed_dp853 at `tolerance` and the file it writes."""
    output = folder / f"relaxed_dp853_{tolerance:.0e}.h5"
    namelist = output.with_suffix(".nml")
    namelist.write_text(SCENE.format(t_end=T_END, tolerance=tolerance, file=output))
    return [bin_dir / "eme_run", namelist], output


def eme_state(output):
    """The state at t_end of an eme_run file: (q, p, gamma) and the temperatures."""
    with h5py.File(output, "r") as f:
        if abs(f["time"][-1] - T_END) > 1e-12 or f.attrs["status"] != "complete":
            raise ProgramFailed(f"{output} did not reach t = {T_END} s: {f.attrs['status']}")
        return np.concatenate([f["state"][-1, :13], f["temperature"][-1]])


def dp5_command(bin_dir, tolerance):
    return [bin_dir / "cvode_baseline", "--arkode-dp5", "--tolerance", f"{tolerance:.1e}", "--t-end", T_END]


def dp5_state(stdout):
    """The state cvode_baseline printed, and its steps."""
    state = np.array([float(x) for x in re.search(r"^state=(.*)$", stdout, re.MULTILINE).group(1).split()])
    return state, int(re.search(r"^steps=(\d+)", stdout, re.MULTILINE).group(1))


def at_error(points, target):
    """log-log interpolation of the instructions at error `target` between the two runs whose
    errors bracket it (points: (error, instructions) pairs), or None."""
    points = sorted(points, reverse=True)
    for (e1, w1), (e2, w2) in zip(points, points[1:]):
        if e1 >= target >= e2 and e1 > e2:
            weight = math.log(e1 / target) / math.log(e1 / e2)
            return math.exp(math.log(w1) + weight * math.log(w2 / w1))
    return None


def measure(bin_dir, _repeats):
    """The runs, in a scratch folder of their own; prints the table and the lines."""
    for tool in ("valgrind", "callgrind_annotate"):
        if shutil.which(tool) is None:
            raise ProgramFailed(f"{tool} is not installed: make bench installs it (Debian: apt-get install valgrind)")
    with tempfile.TemporaryDirectory(prefix="bench_arkode_") as scratch, machine_load.measured(own=1) as load:
        folder = Path(scratch)
        command, output = eme_command(bin_dir, folder, REFERENCE_TOLERANCE)
        run_program(command)
        eme_reference = eme_state(output)
        dp5_reference, _ = dp5_state(run_program(dp5_command(bin_dir, REFERENCE_TOLERANCE)))
        rows, eme_points, dp5_points = [], [], []
        for tolerance in TOLERANCES:
            command, output = eme_command(bin_dir, folder, tolerance)
            counts, _ = callgrind(command, folder, f"eme_{tolerance:.0e}", (EME_WORK,))
            with h5py.File(output, "r") as f:
                eme_steps = int(f.attrs["steps_completed"])
            eme_points.append((error(eme_state(output), eme_reference), counts[EME_WORK]))
            counts, stdout = callgrind(dp5_command(bin_dir, tolerance), folder, f"dp5_{tolerance:.0e}", (DP5_WORK,))
            state, dp5_steps = dp5_state(stdout)
            dp5_points.append((error(state, dp5_reference), counts[DP5_WORK]))
            rows.append((tolerance, *eme_points[-1], eme_steps, *dp5_points[-1], dp5_steps))
    print(f"relaxed_dp853 (eme_run) against ARKODE DP5 (cvode_baseline --arkode-dp5), the paper scene to t = {T_END:g} s; "
          f"error max(|q, p, gamma|, |theta|/300 K) against each code's own run at {REFERENCE_TOLERANCE:g} (the two "
          f"references {error(eme_reference, dp5_reference):.1e} apart); instructions of the integration (callgrind):")
    print(f"  {'tol':>7}  {'dp853 error':>11} {'instructions':>13} {'steps':>6}   {'DP5 error':>10} {'instructions':>13} "
          f"{'steps':>6}")
    for tolerance, e_err, e_work, e_steps, d_err, d_work, d_steps in rows:
        print(f"  {tolerance:7.0e}  {e_err:11.2e} {e_work:13,.0f} {e_steps:6d}   {d_err:10.2e} {d_work:13,.0f} {d_steps:6d}")
    for decade in DECADES:
        eme_work, dp5_work = at_error(eme_points, decade), at_error(dp5_points, decade)
        name = f"relaxed_dp853_over_dp5_at_{decade:.0e}".replace("e-0", "e-")
        if eme_work is None or dp5_work is None:
            print(f"{name}: not measured (the runs of {'relaxed_dp853' if eme_work is None else 'DP5'} do not bracket "
                  f"an error of {decade:.0e})")
        else:
            print(target_line(name, eme_work / dp5_work, 1.0))
    load.report("bench_arkode.py")
    return 0


def main(argv=None):
    return bench_main(argv, __doc__, "eme_run and cvode_baseline", 1, measure)


if __name__ == "__main__":
    sys.exit(main())
