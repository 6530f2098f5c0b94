"""summarize_runs.py on files written with &output every and interval: the same figures as
eme_run's own summary line and as the per-step datasets, whatever the stride."""
import re
import subprocess
import sys
from pathlib import Path

import h5py
import pytest

from conftest import run_eme

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "postprocess"))

import summarize_runs  # noqa: E402

FIXED = {"integrator": {"scheme": "eme", "thermo_variable": "temperature", "dt": 0.01, "t_end": 3.0}}
# Runs that choose their own steps, their rows on a grid of 0.5 s.
GRIDDED = {
    "relaxed_dp853": {"integrator": {"scheme": "relaxed_dp853", "thermo_variable": "temperature", "dt": 0.15,
                                     "t_end": 3.0}},
    "eme_tolerance": {"integrator": {"scheme": "eme", "thermo_variable": "temperature", "dt": 0.05, "t_end": 3.0,
                                     "tolerance": 1e-6}},
}
# (A run that chooses its steps has no plan: "N steps", not "N/M steps".)
SUMMARY_LINE = re.compile(r": complete, (\d+)(?:/\d+)? steps, energy balance <=\s*(\S+), min dS =\s*(\S+) J/K, "
                          r"max dV =\s*(\S+) J, \|dJz\| <=\s*(\S+), Newton/step\s*(\S+),")


def eme_run_summary(stdout):
    """eme_run's printed figures: steps, energy balance, min dS, max dV, J_z drift, Newton/step."""
    found = SUMMARY_LINE.search(stdout)
    assert found, stdout
    steps, *figures = found.groups()
    return int(steps), [float(value) for value in figures]


def run(tmp_path, name, groups, **output):
    groups = {**groups, "output": dict(output)}
    result, path = run_eme(tmp_path, name, groups)
    assert result.returncode == 0, result.stderr
    return path, eme_run_summary(result.stdout)


def check_against_eme_run(path, printed):
    steps, (energy, min_ds, max_dv, jz, newton) = printed
    row = summarize_runs.summarize(path)
    assert row["steps"] == steps
    # eme_run prints three significant digits (Newton/step two decimals).
    for key, value in (("energy_drift", energy), ("min_dS", min_ds), ("max_dV", max_dv), ("jz_drift", jz)):
        assert row[key] == pytest.approx(value, rel=6e-3), (key, row[key], value)
    assert abs(row["newton_per_step"] - newton) <= 0.006, (row["newton_per_step"], newton)
    return row


def check_against_step_records(path, row):
    with h5py.File(path, "r") as f:
        assert row["steps"] == f["step"][-1] == f.attrs["steps_completed"]
        assert row["min_dS"] == f["min_entropy_increment"][()].min()
        assert row["max_dV"] == f["max_lyapunov_increment"][()].max()
        assert row["newton_per_step"] == f["newton_iterations"][()].sum() / f["step"][-1]


@pytest.mark.parametrize("every", [7, 100])
def test_strided_file_gives_eme_runs_figures_and_the_full_files(tmp_path, every):
    full_path, full_printed = run(tmp_path, "full", FIXED)
    path, printed = run(tmp_path, f"every{every}", FIXED, every=every)
    row = check_against_eme_run(path, printed)
    check_against_step_records(path, row)
    with h5py.File(path, "r") as f:
        assert len(f["step"]) == -(-300 // every) < 300          # rows stand for several steps
    # The same run written every step: the same figures, bit for bit where they are per-step.
    full = check_against_eme_run(full_path, full_printed)
    for key in ("steps", "min_dS", "max_dV", "newton_per_step", "rejected"):
        assert row[key] == full[key], key


@pytest.mark.parametrize("name", GRIDDED)
def test_gridded_file_gives_eme_runs_figures(tmp_path, name):
    path, printed = run(tmp_path, name, GRIDDED[name], interval=0.5)
    row = check_against_eme_run(path, printed)
    check_against_step_records(path, row)
    with h5py.File(path, "r") as f:
        assert len(f["step"]) == 6 < row["steps"]
        rejected = f["rejected_steps"][()].sum() if "rejected_steps" in f else None
    if rejected is not None:
        assert row["rejected"] == str(int(rejected))


def test_the_table_prints_the_steps_of_a_strided_file(tmp_path):
    path, (steps, _) = run(tmp_path, "every50", FIXED, every=50)
    result = subprocess.run([sys.executable, str(ROOT / "postprocess" / "summarize_runs.py"), str(path)],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    header, line = result.stdout.splitlines()
    assert line.split()[header.split().index("steps")] == str(steps) == "300"
