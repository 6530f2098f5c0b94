"""postprocess/study_table.py on real studies run with eme_ensemble: a product study gives one
dimension per swept field with its values and units, a zip study one `case` dimension, failed
cases keep their cells with their status, and every cell is its index row."""
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from conftest import BIN

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "postprocess"))

import study_table  # noqa: E402

BASE = ROOT / "inputs" / "paper_fig4_eme_theta.nml"
# 2 schemes x 3 dt x 2 theta(2) x 2 Newton limits: the limit 1 fails every case's first step.
PRODUCT = """&sweep field = 't_end', values = 0.3 /
&sweep field = 'scheme', texts = 'eme', 'midpoint' /
&sweep field = 'dt', values = 0.15, 0.1, 0.05 /
&sweep field = 'theta(2)', values = 340.0, 350.0 /
&sweep field = 'newton_max_iterations', values = 50, 1 /"""
ZIP = """&sweep field = 't_end', values = 0.3, 0.3, 0.3 /
&sweep field = 'scheme', texts = 'eme', 'relaxed_rk4', 'midpoint' /
&sweep field = 'dt', values = 0.1, 0.15, 0.05 /
&sweep field = 'newton_max_iterations', values = 50, 50, 1 /"""


def run_study(directory, name, combine, sweeps):
    namelist = directory / f"{name}.nml"
    namelist.write_text(f"&study base = '{BASE}', output_dir = '{directory / name}', combine = '{combine}' /\n"
                        f"{sweeps}\n")
    result = subprocess.run([str(BIN / "eme_ensemble"), str(namelist)], capture_output=True, text=True,
                            timeout=300)
    assert result.returncode == 0, result.stderr
    return directory / name / "index.h5"


@pytest.fixture(scope="module")
def studies(tmp_path_factory):
    directory = tmp_path_factory.mktemp("study_table")
    return {"product": run_study(directory, "product", "product", PRODUCT),
            "zip": run_study(directory, "zip", "zip", ZIP)}


def index_rows(path):
    with h5py.File(path, "r") as f:
        cases = f["cases"][()]
        units = [u.decode() if isinstance(u, bytes) else u for u in f["cases"].attrs["column_units"]]
    rows = {int(row["case"]): {name: (row[name].decode() if isinstance(row[name], bytes) else row[name].item())
                               for name in cases.dtype.names} for row in cases}
    return rows, dict(zip(cases.dtype.names, units))


def test_a_product_study_has_one_dimension_per_swept_field(studies):
    ds = study_table.open_study(studies["product"])
    assert ds.energy_drift.dims == ("t_end", "scheme", "dt", "theta_2", "newton_max_iterations")
    assert dict(ds.sizes) == {"t_end": 1, "scheme": 2, "dt": 3, "theta_2": 2, "newton_max_iterations": 2}
    assert ds.scheme.values.tolist() == ["eme", "midpoint"]
    assert ds.dt.values.tolist() == [0.15, 0.1, 0.05] and ds.theta_2.values.tolist() == [340.0, 350.0]
    assert ds.theta_2.attrs == {"units": "K", "field": "theta(2)"} and ds.dt.attrs["units"] == "s"
    assert ds.min_entropy_increment.attrs["units"] == "J/K" and ds.energy_drift.attrs["units"] == "1"


def test_every_cell_is_its_index_row_and_failed_cases_keep_theirs(studies):
    ds = study_table.open_study(studies["product"])
    rows, units = index_rows(studies["product"])
    assert ds.case.size == len(rows) == 24
    for row in rows.values():
        cell = ds.sel(scheme=row["scheme"], dt=row["dt"], theta_2=row["theta(2)"],
                      newton_max_iterations=row["newton_max_iterations"]).isel(t_end=0)
        assert int(cell.case) == row["case"]
        for name in ("status", "failure_kind", "steps_completed", "energy_drift", "min_entropy_increment",
                     "solve_time_seconds", "file"):
            expected, got = row[name], cell[name].item()
            if isinstance(expected, float) and np.isnan(expected):
                assert np.isnan(got), name
            else:
                assert got == expected, name
            assert ds[name].attrs["units"] == units[name]
    failed = ds.status.sel(newton_max_iterations=1.0)
    assert failed.size == 12 and all(status.startswith("failed") for status in failed.values.ravel())
    assert all(status == "complete" for status in ds.status.sel(newton_max_iterations=50.0).values.ravel())


def test_a_zip_study_has_one_case_dimension_with_the_swept_values(studies):
    ds = study_table.open_study(studies["zip"])
    rows, _ = index_rows(studies["zip"])
    assert ds.energy_drift.dims == ("case",) and ds.case.values.tolist() == [1, 2, 3]
    assert ds.scheme.values.tolist() == [rows[k]["scheme"] for k in (1, 2, 3)] == ["eme", "relaxed_rk4", "midpoint"]
    assert ds.dt.values.tolist() == [0.1, 0.15, 0.05] and ds.dt.dims == ("case",)
    assert ds.status.values[2].startswith("failed") and ds.status.values[0] == "complete"
    # A product study can be asked for the same layout.
    assert study_table.open_study(studies["product"], dims="case").energy_drift.dims == ("case",)


def test_the_frame_has_a_row_per_case_and_the_units(studies):
    frame = study_table.study_frame(studies["product"])
    rows, units = index_rows(studies["product"])
    assert list(frame.index) == sorted(rows) and list(frame.columns[:5]) == ["t_end", "scheme", "dt", "theta(2)",
                                                                            "newton_max_iterations"]
    assert frame.loc[7, "status"] == rows[7]["status"] and frame.loc[7, "scheme"] == rows[7]["scheme"]
    assert frame.attrs["units"]["theta(2)"] == "K" == units["theta(2)"]


def test_a_file_without_cases_is_named(tmp_path):
    path = tmp_path / "run.h5"
    with h5py.File(path, "w") as f:
        f["time"] = np.zeros(2)
    result = subprocess.run([sys.executable, str(ROOT / "postprocess" / "study_table.py"), str(path)],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 2
    assert result.stderr.strip() == (f"study_table.py: error: {path}: dataset '/cases' is missing; is this an "
                                     "eme_ensemble index.h5?")
