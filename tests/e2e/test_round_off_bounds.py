"""The README's "to round-off": one bound per balance, in ulps of the quantities involved
(docs/faults.md, Every accepted step checked), stated alike by the README, docs/faults.md and
every run file; checked here where round-off shows (EME without conduction: almost no entropy is
produced, and single steps lower S by a few ulps), from the file's own figures and, more
differently, from its points (dS >= -32 eps max|S|, dV <= 64 eps |E_0|: tighter than the
per-step bounds, whose scales hold the springs' thermal terms Cap theta, and met on this scene)."""
import re

import h5py
import numpy as np

from conftest import ROOT, run_eme

EPS = np.finfo(float).eps
BOUND_ULPS = 32


def test_the_docs_and_the_files_state_the_bound_the_code_uses(tmp_path, eme_run_binary):
    readme = " ".join((ROOT / "README.md").read_text().split())
    faults = " ".join((ROOT / "docs" / "faults.md").read_text().split())
    assert f"in ulps of the sums of the absolute values of their terms, at most {BOUND_ULPS}" in readme
    assert re.search(rf"\| energy \| .* \| {BOUND_ULPS} \|", faults)
    assert re.search(r"\| `eme` .*\| yes, to round-off \| yes, to round-off \|", readme)
    result, path = run_eme(tmp_path, "paper", {"integrator": {"t_end": 1.0}})
    assert result.returncode == 0, result.stderr
    with h5py.File(path, "r") as f:
        assert list(f.attrs["balance_bound_ulps"]) == [BOUND_ULPS] * 4


def test_eme_without_conduction_keeps_its_balances_to_round_off(tmp_path, eme_run_binary):
    result, path = run_eme(tmp_path, "no_conduction", {
        "model": {"conductivity": 0.0}, "initial": {"theta(2)": 300.0},
        "integrator": {"scheme": "eme", "thermo_variable": "temperature", "dt": 5e-4}})
    assert result.returncode == 0, result.stderr
    with h5py.File(path, "r") as f:
        assert f.attrs["steps_completed"] == 40000 and f.attrs["resolved_steps"] == 0
        columns = f["balance"].attrs["columns"]
        columns = (columns.decode() if isinstance(columns, bytes) else columns).split()
        figures = f["balance"][()]
        entropy, energy = f["entropy"][()], f["energy"][()]
        lyapunov, min_ds, max_dv = f["lyapunov"][()], f["min_entropy_increment"][()], f["max_lyapunov_increment"][()]
    assert columns == ["energy", "momentum", "entropy", "lyapunov"]
    assert figures.max() <= BOUND_ULPS
    # Round-off shows: the entropy of some steps is within 1 ulp of its scale of falling.
    assert figures[:, columns.index("entropy")].max() > -1
    entropy_bound = 32 * EPS * np.abs(entropy).max()
    lyapunov_bound = 64 * EPS * abs(energy[0])
    assert min_ds.min() >= -entropy_bound and np.diff(entropy).min() >= -entropy_bound
    assert max_dv.max() <= lyapunov_bound and np.diff(lyapunov).max() <= lyapunov_bound
