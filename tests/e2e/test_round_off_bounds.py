"""The README's "to round-off" for dS >= 0 and dV <= 0: the bounds it states are the ones
checked here, on the case where round-off shows (EME without conduction: almost no entropy is
produced, and single steps lower S by a few ulps)."""
import re

import numpy as np

from conftest import ROOT, read_run, run_eme

EPS = np.finfo(float).eps
ENTROPY_ULPS, LYAPUNOV_ULPS = 32, 64


def test_readme_states_the_bounds_the_tests_use():
    text = " ".join((ROOT / "README.md").read_text().split())
    assert f"dS >= -{ENTROPY_ULPS} eps max|S|" in text and f"dV <= {LYAPUNOV_ULPS} eps |E_0|" in text
    assert re.search(r"\| `eme` .*\| yes, to round-off \| yes, to round-off \|", text)


def test_eme_without_conduction_keeps_dS_and_dV_to_round_off(tmp_path, eme_run_binary):
    result, path = run_eme(tmp_path, "no_conduction", {
        "model": {"conductivity": 0.0}, "initial": {"theta(2)": 300.0},
        "integrator": {"scheme": "eme", "thermo_variable": "temperature", "dt": 5e-4}})
    assert result.returncode == 0, result.stderr
    run = read_run(path)
    assert run["attrs"]["steps_completed"] == 40000
    entropy_bound = ENTROPY_ULPS * EPS * np.abs(run["entropy"]).max()
    lyapunov_bound = LYAPUNOV_ULPS * EPS * abs(run["energy"][0])
    # Every step's, from the per-step records and from the points.
    assert run["min_entropy_increment"].min() >= -entropy_bound
    assert np.diff(run["entropy"]).min() >= -entropy_bound
    assert run["max_lyapunov_increment"].max() <= lyapunov_bound
    assert np.diff(run["lyapunov"]).max() <= lyapunov_bound
