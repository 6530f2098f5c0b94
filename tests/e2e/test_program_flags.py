"""Every program in build/bin answers --help, -h, --version and PETSc's -help at once: it prints
and exits with status 0, runs nothing (no benchmark, no run) and needs no input file."""
import re
import subprocess

import pytest

from conftest import BIN, ROOT

# Every program the Makefile builds: one per drivers/*.F90 and drivers/*.c.
PROGRAMS = sorted(path.stem for pattern in ("*.F90", "*.c") for path in (ROOT / "drivers").glob(pattern))
# What a program prints when it does its work rather than answer a flag: the machine-readable last
# lines of the benchmarks (us_per_step=..., rrk8_1e-6_ms=..., snes_fixed_us=...) and a run's or a
# study's summary.
WORK_DONE = re.compile(r"^(\w+=[-+]?\d|.*: complete, (\d+/)?\d+ steps|eme_ensemble: \d+ cases)", re.MULTILINE)


def run(program, flag):
    # The timeout only ends a hang; the assertions below, not the time taken, decide.
    return subprocess.run([str(BIN / program), flag], capture_output=True, text=True, timeout=300, cwd=ROOT)


def test_every_program_is_built():
    assert PROGRAMS and all((BIN / program).exists() for program in PROGRAMS), \
        [program for program in PROGRAMS if not (BIN / program).exists()]
    assert sorted(path.name for path in BIN.iterdir() if path.is_file()) == PROGRAMS


@pytest.mark.parametrize("program", PROGRAMS)
@pytest.mark.parametrize("flag", ["--help", "-h"])
def test_help_prints_the_usage_and_exits(program, flag):
    result = run(program, flag)
    assert (result.returncode, result.stderr) == (0, ""), (result.returncode, result.stderr)
    first = result.stdout.splitlines()[0] if result.stdout else ""
    assert first.startswith("usage: ") and program in first, result.stdout[:200]
    assert not WORK_DONE.search(result.stdout), result.stdout


@pytest.mark.parametrize("program", PROGRAMS)
def test_version_names_the_program_code_and_libraries(program):
    result = run(program, "--version")
    assert (result.returncode, result.stderr) == (0, ""), (result.returncode, result.stderr)
    lines = result.stdout.splitlines()
    release = (ROOT / "VERSION").read_text().strip()
    assert re.fullmatch(rf"{program} \(eme\) {re.escape(release)}( \(git [0-9a-z.-]+\))?", lines[0]), lines[0]
    # Every further line is "library: version", and PETSc's is there (every program uses PETSc but
    # cvode_baseline, which uses SUNDIALS alone).
    libraries = dict(line.split(": ", 1) for line in lines[1:])
    assert len(libraries) == len(lines) - 1, lines
    if program == "cvode_baseline":
        assert "SUNDIALS" in libraries and "PETSc" not in libraries and "MPI" not in libraries, lines
    else:
        assert "PETSc" in libraries, lines


@pytest.mark.parametrize("program", PROGRAMS)
def test_petsc_help_prints_and_exits(program):
    result = run(program, "-help")
    assert (result.returncode, result.stderr) == (0, ""), (result.returncode, result.stderr)
    assert re.search(rf"^usage: .*{program}", result.stdout, re.MULTILINE), result.stdout[-500:]
    assert not WORK_DONE.search(result.stdout), WORK_DONE.search(result.stdout).group(0)
