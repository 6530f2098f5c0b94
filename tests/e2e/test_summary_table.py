"""postprocess/summarize_runs.py computes its columns from the file's numbers."""
import subprocess
import sys

import h5py
import numpy as np
import pytest

from conftest import ROOT

sys.path.insert(0, str(ROOT / "postprocess"))
import summarize_runs  # noqa: E402


def make_file(path, energy, entropy, lyapunov, jz, newton):
    with h5py.File(path, "w") as f:
        f["energy"], f["entropy"], f["lyapunov"] = energy, entropy, lyapunov
        f["angular_momentum"] = np.column_stack([np.zeros_like(jz), np.zeros_like(jz), jz])
        f["newton_iterations"] = newton
        f["boundary_heat"] = np.zeros_like(energy)
        f.attrs.update(scheme="eme", thermo_variable="entropy", discrete_gradient="gonzalez",
                       status="complete", wall_time_seconds=1.5, constraints="none")


def test_columns_from_known_numbers(tmp_path):
    path = tmp_path / "known.h5"
    make_file(path, energy=[10.0, 10.5, 9.0], entropy=[1.0, 1.2, 1.1], lyapunov=[5.0, 4.0, 4.5],
              jz=[-3.0, -3.0, -2.9], newton=[4, 6])
    row = summarize_runs.summarize(path)
    assert row["energy_drift"] == pytest.approx(0.1)          # |9 - 10| / 10
    assert row["min_dS"] == pytest.approx(-0.1)               # S_2 - S_1, n+1 minus n
    assert row["max_dV"] == pytest.approx(0.5)                # V_2 - V_1
    assert row["jz_drift"] == pytest.approx(0.1)
    assert row["newton_per_step"] == pytest.approx(5.0)
    assert row["steps"] == 2 and row["run"] == "eme/entropy/gonzalez"


def test_energy_balance_counts_the_boundary_heat(tmp_path):
    path = tmp_path / "heat.h5"
    make_file(path, energy=[10.0, 8.0, 7.0], entropy=[1.0, 1.0, 1.0], lyapunov=[1.0, 1.0, 1.0],
              jz=[0.0, 0.0, 0.0], newton=[1, 1])
    with h5py.File(path, "a") as f:
        f["boundary_heat"][...] = [0.0, -2.0, -2.5]            # E_n - E_0 - Q_n = 0, 0, -0.5
        f["constraint_residual"] = [[0.0], [1e-3], [-2e-3]]
        f.attrs["constraints"] = "temperature"
    row = summarize_runs.summarize(path)
    assert row["energy_drift"] == pytest.approx(0.05)
    assert row["constraint"] == "2.0e-03" and row["run"].endswith("+ temperature")


def test_missing_dataset_is_named(tmp_path):
    path = tmp_path / "broken.h5"
    with h5py.File(path, "w") as f:
        f["energy"] = [1.0]
        f.attrs["thermo_variable"] = "entropy"      # a thermal run's file, which must have /entropy
    with pytest.raises(summarize_runs.RunFileError, match="dataset /entropy is missing"):
        summarize_runs.summarize(path)
    result = subprocess.run([sys.executable, str(ROOT / "postprocess" / "summarize_runs.py"), str(path)],
                            capture_output=True, text=True)
    assert result.returncode == 2 and "dataset /entropy is missing" in result.stderr
