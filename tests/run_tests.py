#!/usr/bin/env python3
"""Runs every test and ends with one line: "N passed, M failed" (tests/README.md).

The Fortran unit tests are pFUnit suites (tests/unit/test_*.pf), built as one program per suite
in build/tests, under pFUnit or the fallback runner (the Makefile chooses; --runner says which,
and the first line printed names it). Under pFUnit each suite program runs once and writes TAP;
pFUnit's own summary is printed. Under the fallback runner each test runs in a process of its
own (`test_x NAME`), so that a crash fails that test and hides no other. A suite that dies
without reporting counts as one failure. The Python tests (end-to-end runs of the drivers,
postprocessing) run under pytest, on --workers processes (pytest-xdist). Counted are tests: a
pFUnit test (each parameterized case one) and a pytest test.

--quick (make check) runs the unit tests and QUICK_TESTS only: one or two files per area, chosen
to exercise every driver, the paper scene, the input checks and the file layout, without the
tests marked `drawing` (they draw figures with matplotlib, the slowest part, or check the drawn
ones; make test runs them).
"""
import argparse
import os
import re
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ElementTree
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
# The fast subset of make check: the paper scene's structure, bad input and the command line, the
# file layout and provenance, the reference docs' tables, adaptive steps, the step rows, a one-rank
# study, the structure file's statements, the layers, the scripts on synthetic files, and the step
# solver's direct way against SNESSolve. The slow ones (kills,
# signals, studies, convergence, and the drawings: QUICK_SELECTION) are left to make test.
QUICK_TESTS = ["tests/e2e/test_paper_scene.py", "tests/e2e/test_bad_input.py", "tests/e2e/test_command_line.py",
               "tests/e2e/test_output_schema.py", "tests/e2e/test_docs_tables.py", "tests/e2e/test_structure_figure.py",
               "tests/architecture/test_layers.py", "tests/e2e/test_conformance_steps.py",
               "tests/postprocess/test_trajectory.py", "tests/e2e/test_direct_newton.py",
               "tests/e2e/test_adaptive.py::test_rejected_steps_are_never_written_and_the_run_lands_on_t_end",
               # the step rows: an integrator's diagnostics, rows that stand for several steps, a study
               "tests/e2e/test_adaptive.py::test_gamma_outside_its_band_is_a_rejected_step",
               "tests/e2e/test_provenance.py::test_every_n_steps",
               "tests/e2e/test_ensemble.py::test_single_rank_without_mpirun"]
QUICK_SELECTION = ["-m", "not drawing"]
TAP_LINE = re.compile(r"^\s*(not ok|ok)\b(?:\s+\d+)?\s*-?\s*(.*)$")


def tap_counts(lines):
    """(passed, failed names) from TAP-like 'ok - NAME' and 'not ok - NAME' lines."""
    passed, failed = 0, []
    for line in lines:
        match = TAP_LINE.match(line)
        if not match:
            continue
        if match.group(1) == "ok":
            passed += 1
        else:
            failed.append(match.group(2).strip())
    return passed, failed


def run_pfunit_suite(program):
    """One suite under pFUnit: (passed, failed)."""
    with tempfile.TemporaryDirectory() as scratch:
        tap = Path(scratch) / "suite.tap"
        result = subprocess.run([str(program), "-t", str(tap)], capture_output=True, text=True, cwd=ROOT)
        lines = tap.read_text().splitlines() if tap.exists() else []
    passed, failed = tap_counts(lines)
    summary = [line for line in result.stdout.splitlines() if line.strip() and set(line.strip()) - {"."}]
    print(f"{program.name}:", *summary[-3:] if not failed else summary, sep="\n  ")
    if result.returncode not in (0, 2) or passed + len(failed) == 0:
        print(f"FAIL {program.name}: exited with status {result.returncode} after {passed + len(failed)} tests\n"
              f"{result.stderr[-2000:]}")
        failed.append("crash")
    return passed, len(failed)


def run_fallback_suite(program):
    """One suite under the fallback runner, each test in a process of its own: (passed, failed)."""
    listing = subprocess.run([str(program), "--list"], capture_output=True, text=True, cwd=ROOT)
    names = [name for name in listing.stdout.splitlines() if name.strip()] if listing.returncode == 0 else []
    if not names:
        print(f"FAIL {program.name}: --list gave no tests (exit status {listing.returncode})\n{listing.stderr[-2000:]}")
        return 0, 1
    passed = failed = 0
    for name in names:
        result = subprocess.run([str(program), name], capture_output=True, text=True, cwd=ROOT)
        ok, not_ok = tap_counts(result.stdout.splitlines())
        if not_ok:
            print(result.stdout.rstrip())
        if ok + len(not_ok) != 1:
            print(f"FAIL {program.name} {name}: exited with status {result.returncode} without a verdict\n"
                  f"{result.stdout[-2000:]}{result.stderr[-2000:]}")
            not_ok = ["crash"]
            ok = 0
        passed += ok
        failed += len(not_ok)
    print(f"{program.name}: {len(names)} tests, {passed} passed, {failed} failed")
    return passed, failed


def run_units(binary_dir, runner):
    passed = failed = 0
    programs = sorted(Path(binary_dir).glob("test_*"))
    if not programs:
        print(f"FAIL unit tests: no suite programs in {binary_dir} (run make first)")
        return 0, 1
    for program in programs:
        p, f = run_pfunit_suite(program) if runner == "pfunit" else run_fallback_suite(program)
        passed += p
        failed += f
    return passed, failed


def run_pytest(paths, workers, selection=()):
    with tempfile.TemporaryDirectory() as scratch:
        report = Path(scratch) / "pytest.xml"
        parallel = ["-n", str(workers)] if workers > 1 else []
        result = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", *parallel,
                                 *selection, f"--junitxml={report}", *paths], cwd=ROOT)
        if not report.exists():
            print(f"FAIL pytest: no report (exit status {result.returncode})")
            return 0, 1
        suites = ElementTree.parse(report).getroot().iter("testsuite")
        total = failed = skipped = 0
        for suite in suites:
            total += int(suite.get("tests", 0))
            failed += int(suite.get("failures", 0)) + int(suite.get("errors", 0))
            skipped += int(suite.get("skipped", 0))
        if skipped:
            print(f"pytest: {skipped} skipped (counted as failed: every test must run)")
        return total - failed - skipped, failed + skipped


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--bin", default=str(ROOT / "build" / "tests"), help="folder of the unit-test suite programs")
    parser.add_argument("--runner", choices=("pfunit", "fallback"), default="fallback",
                        help="the runner the suites were built for (the Makefile's UNIT_RUNNER)")
    parser.add_argument("--pfunit-dir", default="", help="the pFUnit installation (for the first line)")
    parser.add_argument("--workers", type=int, default=int(os.environ.get("EME_TEST_WORKERS", "1")),
                        help="pytest workers (pytest-xdist); default EME_TEST_WORKERS or 1")
    parser.add_argument("--quick", action="store_true",
                        help="the unit tests and QUICK_TESTS, drawings left out (make check)")
    parser.add_argument("pytest_paths", nargs="*", default=["tests"], help="pytest targets (default: tests)")
    args = parser.parse_args()
    selection = []
    if args.quick:
        args.pytest_paths, selection = QUICK_TESTS, QUICK_SELECTION
    if args.runner == "pfunit":
        print(f"unit tests: pFUnit ({args.pfunit_dir})")
    else:
        print("unit tests: the fallback runner of tests/unit/fallback (no pFUnit found: give PFUNIT_DIR, or see "
              "tests/README.md)")
    unit_passed, unit_failed = run_units(args.bin, args.runner)
    python_passed, python_failed = run_pytest(args.pytest_paths, args.workers, selection)
    print(f"unit tests: {unit_passed} passed, {unit_failed} failed; pytest: {python_passed} passed, "
          f"{python_failed} failed")
    passed, failed = unit_passed + python_passed, unit_failed + python_failed
    print(f"{passed} passed, {failed} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
