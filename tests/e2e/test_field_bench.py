"""build/bin/field_bench, the eme side of make bench's instructions per field evaluation
(postprocess/bench_field.py, issue 42 item 5): it evaluates the paper scene's field as eme_run's
model gives it, and the C side (cvode_baseline --field-evaluations) evaluates drivers/cvode_baseline.c's
field, written apart from the Fortran models. At the same states, in the temperature variable, the
two agree, so the benchmark compares the same work; bad arguments are refused."""
import subprocess

import pytest

from conftest import BIN, ROOT

SCENE = ROOT / "inputs" / "paper_fig4_eme_theta.nml"


def checksum(command):
    """Runs a program; the sum |f| of its last field, from its printed line."""
    result = subprocess.run([str(part) for part in command], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    return float(result.stdout.split("=")[-1])


@pytest.mark.parametrize("evaluations", [1, 4])
def test_field_bench_evaluates_the_c_programs_field(evaluations):
    # Both move the initial state's first coordinate by one rounding unit by the sign of the field
    # before (the same rule in each program), so after k evaluations both fields are at one state.
    ours = checksum([BIN / "field_bench", SCENE, evaluations, "temperature"])
    theirs = checksum([BIN / "cvode_baseline", "--field-evaluations", evaluations])
    assert ours == pytest.approx(theirs, rel=1e-13)
    # In entropy variables the temperature rows are entropy rates: another field, another sum.
    other = checksum([BIN / "field_bench", SCENE, evaluations, "entropy"])
    assert abs(other - theirs) > 1e-3 * theirs


@pytest.mark.parametrize("arguments, said", [
    ([SCENE, 0], "EVALUATIONS must be a whole number >= 1"),
    ([SCENE, "many"], "EVALUATIONS must be a whole number >= 1"),
    ([SCENE, 10, "pressure"], "VARIABLE must be entropy, temperature or internal_energy, not 'pressure'"),
    ([ROOT / "inputs" / "no_such_scene.nml", 10], "no_such_scene.nml"),
    ([SCENE], "usage: field_bench"),
])
def test_field_bench_refuses_bad_arguments(arguments, said):
    result = subprocess.run([str(BIN / "field_bench"), *map(str, arguments)], capture_output=True, text=True, timeout=60)
    assert result.returncode == 2, result
    assert said in result.stderr


def test_cvode_baseline_refuses_a_bad_evaluation_count():
    result = subprocess.run([str(BIN / "cvode_baseline"), "--field-evaluations", "0"], capture_output=True, text=True,
                            timeout=60)
    assert result.returncode == 2 and "K: a whole number >= 1" in result.stderr
