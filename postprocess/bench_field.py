#!/usr/bin/env python3
"""Issue 42's field target (make bench): instructions per evaluation of the paper scene's GENERIC
field z' = f(z), eme's against a C field's.

Instructions (valgrind's callgrind; machine-independent, so they do not move with the load) per
evaluation, each the difference of two evaluation counts (LONG minus SHORT evaluations at the
paper scene's initial state: what a process spends once, start-up and set-up, cancels):
  - eme's field: build/bin/field_bench on inputs/paper_fig4_eme_theta.nml, the model the registry
    builds for the paper scene, through model_interface's `continuous_field`, in entropy variables
    (as the relaxed schemes evaluate it) and in temperature variables (as the C field);
  - the C field: build/bin/cvode_baseline --field-evaluations (drivers/cvode_baseline.c's
    right-hand side, temperature variables, without its Jacobian).
The programs run in turn (eme in entropy variables, C, eme in temperature variables). Printed on their own lines with the target
(bench_eme_run.py's format):
  field_instructions          eme's field in entropy variables, per evaluation   (target 700)
  field_over_c_instructions   eme's field in temperature variables / the C field (no target)
then the machine's load around it (machine_load.py). A program that fails, or a missing valgrind,
ends the script with the message and exit status 1.
"""
import shutil
import sys
import tempfile
from pathlib import Path

import machine_load
from bench_cvode_baseline import callgrind
from bench_eme_run import ROOT, ProgramFailed, bench_main, target_line

SCENE = ROOT / "inputs" / "paper_fig4_eme_theta.nml"
SHORT, LONG = 1000, 3000
TARGET = 700          # issue 42 item 5: instructions per evaluation of the generated field


def per_evaluation(command_of, folder, name):
    """Instructions of one evaluation: callgrind at LONG and SHORT evaluations, the difference
    over the counts' difference."""
    totals = [callgrind(command_of(count), folder, f"{name}_{count}")[0]["total"] for count in (SHORT, LONG)]
    return (totals[1] - totals[0]) / (LONG - SHORT)


def measure(bin_dir, _repeats):
    """The counts, in a scratch folder of their own; prints the lines."""
    for tool in ("valgrind", "callgrind_annotate"):
        if shutil.which(tool) is None:
            raise ProgramFailed(f"{tool} is not installed: make bench installs it (Debian: apt-get install valgrind)")
    with tempfile.TemporaryDirectory(prefix="bench_field_") as scratch, machine_load.measured(own=1) as load:
        folder = Path(scratch)
        eme_entropy = per_evaluation(lambda k: [bin_dir / "field_bench", SCENE, k, "entropy"], folder, "eme_s")
        c_field = per_evaluation(lambda k: [bin_dir / "cvode_baseline", "--field-evaluations", k], folder, "c")
        eme_theta = per_evaluation(lambda k: [bin_dir / "field_bench", SCENE, k, "temperature"], folder, "eme_theta")
    print(f"instructions per field evaluation (callgrind; the paper scene's initial state, {LONG} minus {SHORT} "
          f"evaluations):")
    print(f"  eme's field, entropy variables (field_bench: the registry's model, as the relaxed schemes call it): "
          f"{eme_entropy:,.0f}")
    print(f"  eme's field, temperature variables: {eme_theta:,.0f}")
    print(f"  the C field, temperature variables (cvode_baseline --field-evaluations): {c_field:,.0f}")
    print(f"field_entropy_instructions={eme_entropy:.0f} field_temperature_instructions={eme_theta:.0f} "
          f"c_field_instructions={c_field:.0f}")
    print(target_line("field_instructions", eme_entropy, TARGET))
    print(f"field_over_c_instructions={eme_theta / c_field:.3f}  (no target: the same variables as the C field)")
    load.report("bench_field.py")
    return 0


def main(argv=None):
    return bench_main(argv, __doc__, "field_bench and cvode_baseline", 1, measure)


if __name__ == "__main__":
    sys.exit(main())
