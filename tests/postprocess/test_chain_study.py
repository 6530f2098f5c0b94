"""The chain's studies (postprocess/chain_study.py, plot_chain_temperatures.py; issue 39 item 7):
the stability classification on tiny chains whose answer is known in closed form, and the
temperature picture from both kinds of chain file.

The closed form: two 1D thermoelastic springs without thermomechanical coupling (beta = 0,
mu_eq_slope = 0), at rest at their natural lengths, so the masses stay put and only heat moves. In
the temperature variable with heat capacity c and one link kappa, c dtheta_1/dt = kappa (theta_2 -
theta_1) and c dtheta_2/dt = kappa (theta_1 - theta_2): linear, the difference decaying at rate
lambda = 2 kappa/c. One RK4 step multiplies it by R(-dt lambda), R(z) = 1 + z + z^2/2 + z^3/6 +
z^4/24, so RK4 keeps it bounded exactly while dt lambda <= x*, where R(-x*) = 1 (R stays positive
on the axis), and EME (the midpoint rule on a linear field, the Cayley map (1 - x/2)/(1 + x/2)) at
every dt. The total
energy (the internal energies, linear in theta) is kept by both, so a blow-up shows as a
non-positive temperature.
"""
import csv
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from conftest import BIN, run_eme

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "postprocess"))

import chain_study  # noqa: E402
import plot_chain_temperatures  # noqa: E402
from study_analysis import read_index  # noqa: E402

CAPACITY, KAPPA = 10.0, 1.0
DECAY = 2.0 * KAPPA / CAPACITY          # lambda [1/s]


def rk4_real_limit():
    """x* > 0 with R(-x*) = 1 for RK4 (R > 0 on the axis), from the polynomial's roots (numpy)."""
    # (R(-x) - 1)/x = -1 + x/2 - x^2/6 + x^3/24
    roots = np.roots([1 / 24, -1 / 6, 1 / 2, -1])
    return min(root.real for root in roots if abs(root.imag) < 1e-12 and root.real > 0)


def two_spring_scene(path):
    """The closed-form scene above, as an eme_run namelist (the study's base)."""
    path.write_text(f"""&model
  model_name = 'spring_chain'
  links = 2
  ends = 'fixed-free'
  dimension = 1
  spring_law = 'thermoelastic'
  mass = 1.0
  natural_length = 1.0
  mu_eq_const = 100.0
  mu_eq_slope = 0.0
  beta = 0.0
  heat_capacity = {CAPACITY}
  conductivity = {KAPPA}
/
&initial
  theta = 280.0, 300.0
/
&integrator
  scheme = 'ts_rk4'
  thermo_variable = 'temperature'
  dt = 1.0
  t_end = 1.0
/
&output
  file = '{path.with_suffix('.h5')}'
/
""")
    return path


def run_cases(tmp_path, cases):
    base = two_spring_scene(tmp_path / "two_springs.nml")
    study = tmp_path / "study.nml"
    study.write_text(chain_study.zipped_study(base, tmp_path / "cases", cases, index_only=True))
    chain_study.run_study(BIN, study, ranks=1)
    return read_index(tmp_path / "cases")


def test_rk4_limit_is_the_root_of_its_stability_polynomial():
    x = rk4_real_limit()
    assert abs(chain_study.RK4_REAL - x) < 1e-12, (chain_study.RK4_REAL, x)
    assert abs(abs(1 - x + x**2 / 2 - x**3 / 6 + x**4 / 24) - 1) < 1e-12
    y = chain_study.RK4_IMAGINARY
    assert abs(abs(1 + 1j * y - y**2 / 2 - 1j * y**3 / 6 + y**4 / 24) - 1) < 1e-12


def test_classification_brackets_rk4s_closed_form_limit_and_eme_holds(tmp_path):
    """RK4 over dt from 0.5 to 2 times dt* = x*/lambda: stable up to 0.9 dt*, blown up from 1.1 dt*
    (|R| = 1.5 a step there: 20 steps take the 20 K difference past 280 K); EME at 10 dt* stable."""
    limit = rk4_real_limit() / DECAY
    factors = (0.5, 0.7, 0.9, 1.1, 1.4, 2.0)
    steps = [f * limit for f in factors]
    cases = chain_study.stability_cases(("ts_rk4",), (2,), steps) + \
        chain_study.stability_cases(("eme",), (2,), (10 * limit,))
    rows = run_cases(tmp_path, cases)
    outcome = {(row["scheme"], round(row["dt"] / limit, 6)): chain_study.classify(row) for row in rows}
    for f in factors:
        expected = "stable" if f < 1 else "blow-up"
        assert outcome[("ts_rk4", f)] == expected, (f, outcome[("ts_rk4", f)], expected)
    assert outcome[("eme", 10.0)] == "stable", outcome
    grid = chain_study.stability_grid(rows)["ts_rk4"]
    last, first = chain_study.stable_limit(grid["dt"], grid["outcome"][0])
    assert last < limit < first, (last, limit, first)
    assert abs(last / limit - 0.9) < 1e-9 and abs(first / limit - 1.1) < 1e-9


def test_classification_precedence():
    """Each rule of the definition on its own (the index's figures typed here)."""
    row = {"status": "complete", "energy_drift": 1e-14, "min_temperature": 280.0, "halved_steps": 0}
    assert chain_study.classify(row) == "stable"
    assert chain_study.classify({**row, "halved_steps": 3}) == "halved"
    assert chain_study.classify({**row, "energy_drift": 2 * chain_study.STABLE_ENERGY}) == "energy"
    assert chain_study.classify({**row, "min_temperature": float("nan")}) == "blow-up"
    assert chain_study.classify({**row, "min_temperature": -1.0}) == "blow-up"
    assert chain_study.classify({**row, "status": "failed: step 3: Newton did not converge (no root)"}) == "solver"
    assert chain_study.classify({**row, "status": "failed: a stage left the model's domain"}) == "blow-up"


def chain_files(tmp_path):
    """A dense run file (eme_run: /temperature) and a sparse one (chain_bench: /snapshots) of the
    same 3-spring chain with unequal temperatures."""
    groups = {"model": {"model_name": "spring_chain", "links": 3, "ends": "fixed-free", "dimension": 1},
              "initial": {"theta": [300.0, 280.0, 260.0]},
              "integrator": {"scheme": "eme", "thermo_variable": "temperature", "dt": 0.05, "t_end": 0.2}}
    result, dense = run_eme(tmp_path, "dense", groups)
    assert result.returncode == 0, result.stderr
    snapshots = tmp_path / "snapshots.h5"
    result = subprocess.run([str(BIN / "chain_bench"), str(tmp_path / "dense.nml"), "-chain_steps", "4",
                             "-chain_snapshots", str(snapshots), "-chain_snapshot_every", "1"],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    return dense, snapshots


@pytest.mark.drawing
def test_picture_reads_both_kinds_of_chain_file(tmp_path):
    dense, snapshots = chain_files(tmp_path)
    for path, time_name, theta_name in ((dense, "time", "temperature"),
                                        (snapshots, "snapshots/time", "snapshots/theta")):
        out = tmp_path / f"picture_{path.stem}"
        plot_chain_temperatures.main([str(path), "-o", str(out)])
        assert out.with_suffix(".png").stat().st_size > 0
        with h5py.File(path, "r") as handle:
            time, theta = handle[time_name][()], handle[theta_name][()]
        with open(out.with_suffix(".csv")) as handle:
            table = list(csv.reader(handle))
        assert table[0] == ["time_s", "theta_1_K", "theta_2_K", "theta_3_K"]
        drawn = np.array(table[1:], dtype=float)
        assert drawn.shape == (time.size, 4), (path, drawn.shape)
        assert np.allclose(drawn[:, 0], time, rtol=1e-8, atol=0) and np.allclose(drawn[:, 1:], theta, rtol=1e-8)
        assert theta[0].tolist() == [300.0, 280.0, 260.0], theta[0]
    # The two paths ran the same chain: their last temperatures agree (EME, Newton converged).
    with h5py.File(dense) as a, h5py.File(snapshots) as b:
        assert np.allclose(a["temperature"][-1], b["snapshots/theta"][-1], rtol=1e-8, atol=0)


def test_picture_names_what_a_file_lacks(tmp_path, capsys):
    path = tmp_path / "other.h5"
    with h5py.File(path, "w") as handle:
        handle["time"] = np.zeros(3)
    with pytest.raises(SystemExit) as stop:
        plot_chain_temperatures.main([str(path), "-o", str(tmp_path / "out")])
    assert stop.value.code == 2
    error = capsys.readouterr().err
    assert str(path) in error and "/snapshots/theta" in error and "/temperature" in error, error
    assert not (tmp_path / "out.png").exists()


def test_final_state_reads_both_kinds_of_chain_file_alike(tmp_path):
    """The work-precision chart's error reads each case's last state (final_chain_state): a dense
    run's /state and /temperature and a split run's /snapshots hold the same chain alike (EME,
    Newton to its rounding floor on both paths), each read here from the file's own datasets."""
    groups = {"model": {"model_name": "spring_chain", "links": 4, "ends": "fixed-free", "dimension": 2,
                        "gravity": [0.0, -9.81]},
              "initial": {"theta": [300.0, 280.0, 260.0, 250.0]},
              "integrator": {"scheme": "eme", "thermo_variable": "temperature", "dt": 0.05, "t_end": 0.2,
                             "newton_tol": 1.0e-30}}
    result, dense = run_eme(tmp_path, "dense", groups)
    assert result.returncode == 0, result.stderr
    namelist = tmp_path / "dense.nml"
    split_namelist = tmp_path / "split.nml"
    split_namelist.write_text(namelist.read_text().replace(str(dense), str(tmp_path / "split.h5")))
    result = subprocess.run(["mpirun", "--allow-run-as-root", "--oversubscribe", "-n", "2", str(BIN / "eme_run"),
                             str(split_namelist)], capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    read = {path: chain_study.final_chain_state(path) for path in (dense, tmp_path / "split.h5")}
    with h5py.File(dense, "r") as handle:
        assert read[dense][0] == handle["time"][-1] == pytest.approx(0.2, rel=1e-14)
        assert np.array_equal(read[dense][2], handle["temperature"][-1])
        assert read[dense][3] == np.atleast_1d(handle.attrs["theta_ref"])[0]  # one for all springs here
    with h5py.File(tmp_path / "split.h5", "r") as handle:
        assert "state" not in handle
        snapshot = [handle[f"snapshots/{name}"][-1] for name in ("q", "p", "gamma", "theta")]
        assert read[tmp_path / "split.h5"][0] == handle["snapshots/time"][-1]
        assert np.array_equal(read[tmp_path / "split.h5"][1], np.concatenate([v.ravel() for v in snapshot[:3]]))
        assert np.array_equal(read[tmp_path / "split.h5"][2], snapshot[3])
    (time_a, mechanical_a, theta_a, _), (time_b, mechanical_b, theta_b, _) = read.values()
    assert time_a == time_b and np.max(np.abs(mechanical_a)) > 1e-3        # the chain moved
    assert chain_study.chain_error(read[dense], read[tmp_path / "split.h5"]) < 1e-12
    assert np.allclose(np.sort(mechanical_a), np.sort(mechanical_b), rtol=0, atol=1e-12)


def test_heat_base_cuts_the_hot_rod_into_n_springs(tmp_path):
    """The chart's base: inputs/chain_rod_heat.nml with links = 7, its hot and cold halves 3 and 4
    springs, the state written at the start and end only; eme_run runs it from those temperatures."""
    base = tmp_path / "base.nml"
    chain_study.heat_base(ROOT / "inputs" / "chain_rod_heat.nml", 7, base)
    text = base.read_text()
    assert "links = 7" in text and "theta = 3*340.0, 4*280.0" in text and "snapshot_every = 0" in text
    text = text.replace("results/chain_rod_heat.h5", str(tmp_path / "base.h5")).replace("t_end = 2.0", "t_end = 0.02")
    base.write_text(text)
    result = subprocess.run([str(BIN / "eme_run"), str(base)], capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    with h5py.File(tmp_path / "base.h5", "r") as handle:
        assert handle.attrs["links"] == 7
        assert handle["temperature"][0].tolist() == [340.0] * 3 + [280.0] * 4
