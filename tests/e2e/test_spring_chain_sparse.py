"""The spring chain on the sparse, distributed path (src/model/spring_chain/spring_chain_dmda.F90 and its
submodules spring_chain_dmda_*.F90, driven by build/bin/chain_bench; docs/formulation.md section 10, "Sparse and distributed"):
- it takes the dense path's steps: from the same input, the state after 12 steps agrees with
  eme_run's (the generic step residual of the model interface, dense LU) to 1e-10, over
  dimensions, ends, rungs, thermodynamic variables, both discrete gradients and the midpoint rule;
- one rank and two give the same run: 100 steps of a dissipative chain with Newton at its rounding
  floor agree to 1e-10 in the state, E and S, for a 1D fixed-fixed chain and a 3D hanging one;
- at 2000 springs every step keeps E to round-off (1e-13 relative) and S rises;
- what the path cannot run is refused (exit 2, naming the field). eme_run's runs on this path are
  tests/e2e/test_split_runs.py's."""
import math
import re
import subprocess

import h5py
import numpy as np
import pytest

from conftest import BIN, namelist_text, run_eme

MPIRUN = ["mpirun", "--allow-run-as-root", "--oversubscribe"]


def chain_groups(links=4, dimension=3, ends="fixed-free", law="thermoviscoelastic", variable="temperature",
                 scheme="eme", gradient="gonzalez", dt=0.01, steps=12, newton_tol=1.0e-13):
    """A small chain of unlike springs with a temperature gradient, released from a stretch."""
    springs = links + (1 if ends == "fixed-fixed" else 0)
    model = {"model_name": "spring_chain", "links": links, "ends": ends, "dimension": dimension,
             "gravity": [0.0] * (dimension - 1) + [-9.81] if ends == "fixed-free" else [0.0] * dimension,
             "spring_law": law, "mass": 1.0, "natural_length": 1.0,
             "mu_eq_const": [300.0 - 100.0 * a / springs for a in range(springs)]}
    if ends == "fixed-fixed":
        model["span"] = 1.1 * springs
    if law != "elastic":
        model["conductivity"] = 2.0
    initial = {}
    if law != "elastic":
        initial["theta"] = [280.0 + 60.0 * a / max(1, springs - 1) for a in range(springs)]
    if dimension > 1:
        # Off the line so that the chain swings (a chain along x under gravity along the last axis).
        x = []
        for i in range(1, links + 1):
            x += [1.05 * i] + [0.0] * (dimension - 2) + [0.1 * math.sin(i)]
        initial["x"] = x
    elif ends == "fixed-free":
        initial["x"] = [1.05 * i + 0.02 * math.sin(i) for i in range(1, links + 1)]
    integrator = {"scheme": scheme, "dt": dt, "t_end": dt * steps, "newton_tol": newton_tol}
    if law != "elastic":
        integrator["thermo_variable"] = variable
    if scheme == "eme":
        integrator["discrete_gradient"] = gradient
    return {"model": model, "initial": initial, "integrator": integrator}


def run_bench(directory, name, groups, ranks=1, *options):
    """chain_bench on `groups` over `ranks`: its figures (key=value) and the final state."""
    groups = {key: dict(fields) for key, fields in groups.items()}
    groups.setdefault("output", {})["file"] = str(directory / f"{name}.h5")
    namelist = directory / f"{name}.nml"
    namelist.write_text(namelist_text(groups))
    dump = directory / f"{name}.state"
    command = [str(BIN / "chain_bench"), str(namelist), "-chain_dump", str(dump), *options]
    if ranks > 1:
        command = [*MPIRUN, "-n", str(ranks), *command]
    result = subprocess.run(command, capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr
    line = next(line for line in result.stdout.splitlines() if line.startswith("chain_bench:"))
    figures = dict(re.findall(r"(\w+)=\s*(\S+)", line))
    rows = np.vstack([np.loadtxt(directory / f"{name}.state.{rank}", ndmin=2) for rank in range(ranks)])
    state = rows[np.argsort(rows[:, 0]), 1]
    assert np.array_equal(np.sort(rows[:, 0]), np.arange(1, rows.shape[0] + 1))   # every row once
    return figures, state


def assert_states_agree(a, b, tolerance):
    unknowns = min(a.size, b.size)          # fixed-fixed: the DMDA's last point has unused slots
    scale = np.maximum(1.0, np.abs(b[:unknowns]))
    assert np.max(np.abs(a[:unknowns] - b[:unknowns]) / scale) <= tolerance
    assert np.all(a[unknowns:] == 0.0) and np.all(b[unknowns:] == 0.0)


CASES = [
    dict(dimension=3, ends="fixed-free", law="thermoviscoelastic", variable="entropy"),
    dict(dimension=3, ends="fixed-free", law="thermoviscoelastic", variable="temperature", gradient="partitioned"),
    dict(dimension=2, ends="fixed-fixed", law="thermoviscoelastic", variable="internal_energy"),
    dict(dimension=1, ends="fixed-fixed", law="thermoelastic", variable="temperature"),
    dict(dimension=2, ends="fixed-free", law="elastic"),
    dict(dimension=3, ends="fixed-fixed", law="thermoviscoelastic", variable="temperature", scheme="midpoint"),
]


@pytest.mark.parametrize("case", CASES, ids=lambda c: "-".join(str(v) for v in c.values()))
def test_the_sparse_path_takes_the_dense_paths_steps(tmp_path, case):
    groups = chain_groups(**case)
    result, output = run_eme(tmp_path, "dense", groups)
    assert result.returncode == 0, result.stderr
    with h5py.File(output, "r") as f:
        dense = f["state"][-1]
        energy = f["energy"][-1]
        entropy = f["entropy"][-1] if "entropy" in f else 0.0       # elastic springs have none
    figures, sparse = run_bench(tmp_path, "sparse", groups)
    assert int(figures["steps"]) == 12
    assert_states_agree(sparse, dense, 1e-10)
    assert float(figures["energy"]) == pytest.approx(energy, rel=1e-12)
    assert float(figures["entropy"]) == pytest.approx(entropy, rel=1e-12, abs=1e-300)


@pytest.mark.parametrize("case", CASES, ids=lambda c: "-".join(str(v) for v in c.values()))
def test_the_jacobian_holds_every_derivative_of_the_blocks(tmp_path, case):
    """The Jacobian's matrix holds the blocks' structural nonzeros only (coupling_pattern in
    spring_chain_dmda); with -chain_check_pattern its callback fails (exit 1) when a derivative
    the blocks compute (field_rows' band) falls outside them. Eight masses give interior rows and
    both ends' rows, on one rank and across two."""
    groups = chain_groups(links=8, steps=3, **case)
    for ranks in (1, 2):
        figures, _ = run_bench(tmp_path, f"pattern{ranks}", groups, ranks, "-chain_check_pattern")
        assert int(figures["steps"]) == 3 and int(figures["newton"]) >= 3


@pytest.mark.parametrize("shape", [dict(links=40, dimension=1, ends="fixed-fixed"),
                                   dict(links=12, dimension=3, ends="fixed-free")], ids=["1d-fixed-fixed", "3d-hanging"])
def test_one_rank_and_two_give_the_same_run(tmp_path, shape):
    # newton_tol far below rounding: each step's Newton stops at its rounding floor.
    groups = chain_groups(**shape, steps=100, dt=0.005, newton_tol=1.0e-30)
    one, state_one = run_bench(tmp_path, "one", groups)
    two, state_two = run_bench(tmp_path, "two", groups, 2)
    assert int(one["steps"]) == int(two["steps"]) == 100
    assert_states_agree(state_two, state_one, 1e-10)
    for key in ("energy", "entropy"):
        assert float(two[key]) == pytest.approx(float(one[key]), rel=1e-12)
    # A dissipative run: S rose, and it is no state at rest.
    assert float(one["entropy"]) > float(one["entropy_0"])


def rod_groups(n_springs, steps, dt=1.0e-4):
    """The continuum family of docs/formulation.md section 10 (a 1 m rod, EA = 1e4 N, rho A = 1
    kg/m, c = 100 J/(K m), k A = 1 W m/K, eta A = 10 N s, E^neq A = 1e3 N), 1D fixed-fixed, 1 %
    pre-stretch, a half-sine of 20 K on 300 K."""
    h = 1.0 / n_springs
    model = {"model_name": "spring_chain", "links": n_springs - 1, "ends": "fixed-fixed", "span": 1.01, "dimension": 1,
             "gravity": [0.0], "spring_law": "thermoviscoelastic", "mass": h, "natural_length": h,
             "mu_eq_const": 1.0e4 * h, "mu_eq_slope": 0.0, "beta": h, "heat_capacity": 100.0 * h, "theta_ref": 300.0,
             "beta_v": 0.5, "mu_neq_const": 1.0e3 / h, "mu_neq_slope": 0.0, "viscosity_const": 10.0 / h,
             "viscosity_activation": 10.0, "conductivity": 1.0 / h}
    theta = [300.0 + 20.0 * math.sin(math.pi * (a + 0.5) / n_springs) for a in range(n_springs)]
    return {"model": model, "initial": {"theta": theta},
            "integrator": {"scheme": "eme", "dt": dt, "t_end": dt * steps, "newton_tol": 1.0e-9}}


def test_every_step_of_a_long_rod_keeps_energy_to_round_off(tmp_path):
    figures, state = run_bench(tmp_path, "rod", rod_groups(2000, 5))
    assert int(figures["steps"]) == 5 and int(figures["unknowns"]) == 4 * 2000 - 2
    assert float(figures["max_energy_error"]) <= 1e-13
    assert float(figures["min_entropy_increment"]) > 0.0
    assert np.all(np.isfinite(state))


@pytest.mark.parametrize("change, field", [({"scheme": "relaxed_dp853"}, "scheme"),
                                           ({"tolerance": 1e-6}, "tolerance")])
def test_what_the_sparse_path_cannot_run_is_refused(tmp_path, change, field):
    groups = chain_groups()
    groups["integrator"].update(change)
    groups["integrator"].pop("discrete_gradient", None) if change.get("scheme") else None
    groups["output"] = {"file": str(tmp_path / "refused.h5")}
    namelist = tmp_path / "refused.nml"
    namelist.write_text(namelist_text(groups))
    result = subprocess.run([str(BIN / "chain_bench"), str(namelist)], capture_output=True, text=True, timeout=120)
    assert result.returncode == 2, result.stderr
    assert f"&integrator: {field}" in result.stderr and "refused.nml" in result.stderr
    assert not list(tmp_path.glob("refused.state*"))


def test_a_refused_list_of_many_values_is_quoted_short(tmp_path):
    """A refused field of 2000 values: the message names the first value outside the field's
    bounds by its namelist subscript (1-based) and the number given, not the whole list (nor the
    reading array's unset tail), and comes at once."""
    groups = rod_groups(2000, 1)
    groups["model"]["mu_eq_const"] = [10.0] * 1500 + [-1.0] + [10.0] * 499
    groups["output"] = {"file": str(tmp_path / "refused.h5")}
    namelist = tmp_path / "refused.nml"
    namelist.write_text(namelist_text(groups))
    result = subprocess.run([str(BIN / "chain_bench"), str(namelist)], capture_output=True, text=True, timeout=60)
    assert result.returncode == 2
    assert "&model: mu_eq_const(1501) = -1.0 (value 1501 of 2000) is not allowed; allowed: " in result.stderr
    assert len(result.stderr) < 1000


def test_a_temperature_above_its_springs_stiffness_bound_is_named_alone(tmp_path):
    """One of 300 namelist temperatures above its spring's bound theta_ref + mu_eq_const/mu_eq_slope
    (300 + 200/0.5 = 700 K): the message names that value by its subscript and its spring, not the
    300 values (2,278 bytes before)."""
    groups = {"model": {"model_name": "spring_chain", "links": 300, "dimension": 1},
              "initial": {"theta": [300.0] * 123 + [800.0] + [300.0] * 176},
              "output": {"file": str(tmp_path / "refused.h5")}}
    namelist = tmp_path / "refused.nml"
    namelist.write_text(namelist_text(groups))
    result = subprocess.run([str(BIN / "eme_run"), str(namelist)], capture_output=True, text=True, timeout=60)
    assert result.returncode == 2
    assert ("&initial: theta(124) = 800.0 is not allowed: spring 124's stiffness mu_eq(theta) of eq. (17) is -50.0 J"
            in result.stderr), result.stderr
    assert len(result.stderr) < 400 and not list(tmp_path.glob("refused.h5*"))


def test_snapshots_of_a_split_chain_are_its_state(tmp_path):
    """-chain_snapshots: /snapshots holds the start, every 4th step and the last; written from two
    ranks it equals the one-rank file, and its last q, p, gamma, theta are the final state's rows
    (the temperature variable: theta is tau), exactly."""
    groups = chain_groups(links=12, dimension=3, ends="fixed-free", steps=10)
    files = {}
    for ranks in (1, 2):
        files[ranks] = tmp_path / f"snapshots{ranks}.h5"
        figures, state = run_bench(tmp_path, f"run{ranks}", groups, ranks, "-chain_snapshots", str(files[ranks]),
                                   "-chain_snapshot_every", "4")
    with h5py.File(files[1], "r") as one, h5py.File(files[2], "r") as two:
        assert np.allclose(one["snapshots/time"][()], [0.0, 0.04, 0.08, 0.10], rtol=0, atol=1e-15)
        assert one["snapshots/q"].shape == (4, 12, 3) and one["snapshots/theta"].shape == (4, 12)
        for name in ("q", "p", "gamma", "theta"):
            assert np.max(np.abs(one[f"snapshots/{name}"][()] - two[f"snapshots/{name}"][()])) <= 1e-12
        point = 3 + 3 + 1 + 1                                  # x, p, gamma, tau of each mass and spring
        rows = state.reshape(12, point)                        # the two-rank run's final state
        assert np.array_equal(two["snapshots/q"][-1], rows[:, 0:3])
        assert np.array_equal(two["snapshots/p"][-1], rows[:, 3:6])
        assert np.array_equal(two["snapshots/gamma"][-1], rows[:, 6])
        assert np.array_equal(two["snapshots/theta"][-1], rows[:, 7])
