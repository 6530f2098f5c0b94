"""One spelling of the springs' thermodynamic columns: /state's s_1 s_2, theta_1 theta_2 or
u_1 u_2 by the run's variable, as /temperature's theta_1 theta_2; the scripts read files of
either spelling (older files wrote theta1)."""
import sys

import h5py
import numpy as np
import pytest

from conftest import ROOT, run_eme

sys.path.insert(0, str(ROOT / "postprocess"))

from trajectory import read_run  # noqa: E402

SYMBOLS = {"entropy": "s", "temperature": "theta", "internal_energy": "u"}


@pytest.mark.parametrize("variable", SYMBOLS)
def test_state_columns_are_spelt_as_the_temperature_columns(tmp_path, eme_run_binary, variable):
    result, path = run_eme(tmp_path, variable, {"integrator": {"thermo_variable": variable, "t_end": 0.3}})
    assert result.returncode == 0, result.stderr
    with h5py.File(path, "r") as f:
        state = f["state"].attrs["columns"].split()
        temperature = f["temperature"].attrs["columns"].split()
    symbol = SYMBOLS[variable]
    assert state[-2:] == [f"{symbol}_1", f"{symbol}_2"]
    assert temperature == ["theta_1", "theta_2"]
    if variable == "temperature":
        assert state[-2:] == temperature


def test_scripts_read_either_spelling(tmp_path, eme_run_binary):
    """A file rewritten with the older spelling theta1 theta2 reads as the new one."""
    result, path = run_eme(tmp_path, "new", {"integrator": {"thermo_variable": "temperature", "t_end": 0.3}})
    assert result.returncode == 0, result.stderr
    old = tmp_path / "old.h5"
    old.write_bytes(path.read_bytes())
    with h5py.File(old, "r+") as f:
        del f.attrs["text_checksum"]         # a file of that age has none (and the edit would fail it)
        f["state"].attrs["columns"] = f["state"].attrs["columns"].replace("theta_1", "theta1").replace("theta_2",
                                                                                                      "theta2")
    new_run, old_run = read_run(path, ["state"]), read_run(old, ["state"])
    for name in ("theta_1", "theta1", "theta_2", "theta2"):
        np.testing.assert_array_equal(new_run.column("state", name), old_run.column("state", name))
    with h5py.File(path, "r") as f:
        np.testing.assert_array_equal(new_run.column("state", "theta1"), f["temperature"][:, 0])
