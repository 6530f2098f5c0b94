#!/usr/bin/env python3
"""Runs every test and ends with one line: "N passed, M failed".

Fortran unit-test programs (build/tests/test_*) register their tests by name (`test_x --list`);
each test runs in a process of its own (`test_x NAME`) and prints one "PASS ..." or "FAIL ..."
line per check; a test that dies without reporting a failure counts as one failure. The Python tests
(end-to-end runs of the drivers, postprocessing) run under pytest and are counted per test.
"""
import argparse
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ElementTree
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def run_fortran(binary_dir):
    """Runs every registered test of every program in a process of its own (tests/unit/test_runner.f90),
    so that a crash in one test is reported as that test's failure and hides no other."""
    passed = failed = 0
    for program in sorted(Path(binary_dir).glob("test_*")):
        listing = subprocess.run([str(program), "--list"], capture_output=True, text=True, cwd=ROOT)
        names = listing.stdout.split("\n") if listing.returncode == 0 else []
        names = [name for name in names if name.strip()]
        if not names:
            print(f"FAIL {program.name}: --list gave no tests (exit status {listing.returncode})\n"
                  f"{listing.stderr[-2000:]}")
            failed += 1
            continue
        program_passed = program_failed = 0
        for name in names:
            result = subprocess.run([str(program), name], capture_output=True, text=True, cwd=ROOT)
            lines = result.stdout.splitlines()
            passes = sum(line.startswith("PASS ") for line in lines)
            failures = [line for line in lines if line.startswith("FAIL ")]
            for line in failures:
                print(line)
            if result.returncode != 0 and not failures:
                print(f"FAIL {program.name} {name}: exited with status {result.returncode}\n{result.stderr[-2000:]}")
                failures = ["crash"]
            if passes + len(failures) == 0:
                print(f"FAIL {program.name} {name}: made no check")
                failures = ["no check"]
            program_passed += passes
            program_failed += len(failures)
        print(f"{program.name}: {len(names)} tests, {program_passed} checks passed, {program_failed} failed")
        passed += program_passed
        failed += program_failed
    return passed, failed


def run_pytest(paths):
    with tempfile.TemporaryDirectory() as scratch:
        report = Path(scratch) / "pytest.xml"
        result = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                                 f"--junitxml={report}", *paths], cwd=ROOT)
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
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--bin", default=str(ROOT / "build" / "tests"), help="folder of Fortran test programs")
    parser.add_argument("pytest_paths", nargs="*", default=["tests"], help="pytest targets (default: tests)")
    args = parser.parse_args()
    fortran_passed, fortran_failed = run_fortran(args.bin)
    python_passed, python_failed = run_pytest(args.pytest_paths)
    passed, failed = fortran_passed + python_passed, fortran_failed + python_failed
    print(f"{passed} passed, {failed} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
