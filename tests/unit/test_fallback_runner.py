"""The fallback runner (tests/unit/fallback) runs the pFUnit suites without pFUnit: a failing
assertion fails its test with its message and location, the test stops at it, the other tests
still run and pass, a crash shows in the exit status, --list and test names select tests, and
syntax outside the handled subset is refused."""
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
FALLBACK = ROOT / "tests" / "unit" / "fallback"

SUITE = """module test_sample
  use, intrinsic :: iso_fortran_env, only: real64
  use funit, only: assertTrue, assertFalse, assertEqual, anyExceptions, SourceLocation
  implicit none
  integer :: calls = 0, after_failure = 0
contains
  @before
  subroutine count_calls()
    calls = calls + 1
  end subroutine count_calls

  @test
  subroutine passes()
    @assertTrue(calls >= 1, message='@before ran')
    @assertEqual([1.0_real64, 2.0_real64], [1.0_real64, 2.0_real64 + 1e-9_real64], tolerance=1e-6_real64)
    @assertEqual(3, 3, message='integers')
    @assertFalse(.false.)
  end subroutine passes

  @test
  subroutine fails()
    @assertEqual([1.0_real64, 2.0_real64], [1.0_real64, 2.5_real64], tolerance=1e-6_real64, message='arrays differ')
    after_failure = 1
    error stop 'the test did not stop at its failed assertion'
  end subroutine fails

  @test
  subroutine crashes()
    error stop 'crash'
  end subroutine crashes
end module test_sample
"""


@pytest.fixture(scope="module")
def sample(tmp_path_factory):
    """The sample suite built with the fallback: (driver program, folder)."""
    compiler = shutil.which("gfortran")
    if compiler is None:
        pytest.fail("gfortran is needed (make installs it)")
    folder = tmp_path_factory.mktemp("fallback")
    (folder / "test_sample.pf").write_text(SUITE)
    result = subprocess.run([sys.executable, str(FALLBACK / "pf_lite.py"), str(folder / "test_sample.pf"),
                             str(folder)], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    for source in (FALLBACK / "funit.f90", folder / "test_sample.F90", folder / "test_sample_driver.F90"):
        result = subprocess.run([compiler, "-ffree-line-length-none", "-c", str(source)], capture_output=True,
                                text=True, cwd=folder)
        assert result.returncode == 0, result.stderr
    result = subprocess.run([compiler, "-o", "sample", "funit.o", "test_sample.o", "test_sample_driver.o"],
                            capture_output=True, text=True, cwd=folder)
    assert result.returncode == 0, result.stderr
    return folder / "sample", folder


def run(program, *arguments):
    return subprocess.run([str(program), *arguments], capture_output=True, text=True, timeout=60)


def test_lists_the_tests(sample):
    program, _ = sample
    assert run(program, "--list").stdout.split() == ["passes", "fails", "crashes"]


def test_a_passing_test(sample):
    program, _ = sample
    result = run(program, "passes")
    assert result.returncode == 0
    assert result.stdout.splitlines()[-2:] == ["ok - test_sample.passes", "OK (1 tests)"]


def test_a_failing_assertion_fails_its_test_with_message_and_location(sample):
    program, _ = sample
    result = run(program, "fails", "passes")
    assert result.returncode == 1, result.stdout + result.stderr
    text = result.stdout
    line = next(n for n, text in enumerate(SUITE.splitlines(), start=1) if "arrays differ" in text)
    assert "Failure in: test_sample.fails" in text and f"Location: [test_sample.pf:{line}]" in text
    assert "arrays differ" in text and "at index [2]" in text
    assert "did not stop" not in text + result.stderr        # the test returned at its failure
    assert "not ok - test_sample.fails" in text and "ok - test_sample.passes" in text
    assert text.splitlines()[-1] == "FAILURES!!! Tests run: 2, Failures: 1"


def test_a_crash_is_not_a_pass(sample):
    program, _ = sample
    result = run(program, "crashes")
    assert result.returncode != 0 and "ok - test_sample.crashes" not in result.stdout


def test_an_unknown_name_is_refused(sample):
    program, _ = sample
    result = run(program, "missing")
    assert result.returncode == 2 and "no test named 'missing'" in result.stdout


@pytest.mark.parametrize("line, words", [("  @mpiTest(npes=[1, 2])", "@mpiTest is not in the fallback's subset"),
                                          ("  @assertTrue(x .and. &", "must be one whole line")])
def test_syntax_outside_the_subset_is_refused(tmp_path, line, words):
    (tmp_path / "test_bad.pf").write_text(SUITE.replace("contains\n", f"{line}\ncontains\n", 1)
                                          if "mpiTest" in line else SUITE.replace(
                                              "    @assertFalse(.false.)", line))
    result = subprocess.run([sys.executable, str(FALLBACK / "pf_lite.py"), str(tmp_path / "test_bad.pf"),
                             str(tmp_path / "out")], capture_output=True, text=True)
    assert result.returncode == 1 and words in result.stderr


def test_the_project_s_suites_use_only_the_subset(tmp_path):
    """Every suite of tests/unit is translatable by the fallback (so both runners run the same files)."""
    for suite in sorted((ROOT / "tests" / "unit").glob("test_*.pf")):
        result = subprocess.run([sys.executable, str(FALLBACK / "pf_lite.py"), str(suite), str(tmp_path)],
                                capture_output=True, text=True)
        assert result.returncode == 0, (suite.name, result.stderr)
