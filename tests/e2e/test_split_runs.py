"""eme_run on a model split over ranks (src/run/distributed_simulation.f90, the spring chain's
sparse path): `mpirun -n P eme_run FILE.nml`, and one rank beyond the dense path's 1000 unknowns.
- A split run is the dense run: from the same input, two ranks give the dense path's per-point E, S,
  V and conserved momentum to 1e-12, and its snapshots hold the dense /state's rows to 1e-10, at
  the start, every `snapshot_every`-th step and the last;
- its file is a run file without the state in rows (no /state, /temperature), every step checked
  (/balance within its bounds) with each viscous branch's and link's entropy production >= 0;
- a chain of 1198 unknowns runs on one rank (no mpirun) on the split path;
- what the split path cannot run is refused before anything is written (exit 2);
- a split run stopped by SIGTERM keeps a valid file, marked incomplete, with its snapshots."""
import os
import signal
import subprocess
import time

import h5py
import numpy as np
import pytest

from conftest import BIN, namelist_text, run_eme
from test_spring_chain_sparse import MPIRUN, chain_groups, rod_groups


def write_input(directory, name, groups):
    groups = {key: dict(fields) for key, fields in groups.items()}
    groups.setdefault("output", {})["file"] = str(directory / f"{name}.h5")
    namelist = directory / f"{name}.nml"
    namelist.write_text(namelist_text(groups))
    return namelist, directory / f"{name}.h5"


def run_split(directory, name, groups, ranks=2, *options):
    namelist, output = write_input(directory, name, groups)
    command = [*MPIRUN, "-n", str(ranks), str(BIN / "eme_run"), str(namelist), *options]
    return subprocess.run(command, capture_output=True, text=True, timeout=600), output


def snapshot_rows(state, links, dimension, fixed_fixed):
    """q, p (masses x dimension), gamma and tau (springs) of a dense thermoviscoelastic /state row:
    point k holds x_k, p_k, gamma_k, tau_k; a fixed-fixed chain's last spring follows."""
    point = 2 * dimension + 2
    rows = state[:links * point].reshape(links, point)
    gamma, tau = rows[:, 2 * dimension], rows[:, 2 * dimension + 1]
    if fixed_fixed:
        gamma, tau = np.append(gamma, state[-2]), np.append(tau, state[-1])
    return rows[:, :dimension], rows[:, dimension:2 * dimension], gamma, tau


@pytest.mark.parametrize("shape", [dict(links=40, dimension=1, ends="fixed-fixed"),
                                   dict(links=12, dimension=3, ends="fixed-free")], ids=["1d-fixed-fixed", "3d-hanging"])
def test_a_split_run_is_the_dense_run(tmp_path, shape):
    # newton_tol far below rounding: each step's Newton stops at its rounding floor on both paths.
    groups = chain_groups(**shape, steps=100, dt=0.005, newton_tol=1.0e-30)
    groups["output"] = {"snapshot_every": 25}
    result, dense_file = run_eme(tmp_path, "dense", groups)
    assert result.returncode == 0, result.stderr
    result, split_file = run_split(tmp_path, "split", groups)
    assert result.returncode == 0, result.stderr
    assert result.stdout.count("split.h5: complete, 100/100 steps") == 1       # rank 0 alone reports
    with h5py.File(dense_file, "r") as dense, h5py.File(split_file, "r") as split:
        assert split.attrs["status"] == "complete" and split.attrs["failure_kind"] == "none"
        assert "state" not in split and "temperature" not in split
        assert np.array_equal(split["time"][()], dense["time"][()])
        for name in ("energy", "entropy", "lyapunov"):
            scale = np.max(np.abs(dense[name][()]))
            assert np.max(np.abs(split[name][()] - dense[name][()])) <= 1e-12 * scale, name
        if "angular_momentum" in dense:
            assert np.max(np.abs(split["angular_momentum"][()] - dense["angular_momentum"][()])) <= 1e-10
        steps = [0, 25, 50, 75, 100]
        assert np.allclose(split["snapshots/time"][()], dense["time"][steps], rtol=0, atol=1e-14)
        for row, k in enumerate(steps):
            q, p, gamma, theta = snapshot_rows(dense["state"][k], shape["links"], shape["dimension"],
                                               shape["ends"] == "fixed-fixed")
            for name, expected in (("q", q), ("p", p), ("gamma", gamma), ("theta", theta)):
                got = split[f"snapshots/{name}"][row]
                assert np.max(np.abs(got - expected)) <= 1e-10 * max(1.0, np.max(np.abs(expected))), (name, k)
        # Every step checked, and every branch's and link's entropy production is >= 0.
        balance = split["balance"][()]
        assert np.all(balance[np.isfinite(balance)] <= 32.0)
        assert np.all(split["min_viscous_production"][()] >= 0.0)
        assert np.all(split["min_link_production"][()] >= 0.0)
        assert np.all(split["newton_iterations"][()] >= 1)


def test_a_chain_beyond_the_dense_limit_runs_split_on_one_rank(tmp_path):
    """300 springs of the rod family (1198 unknowns): eme_run alone takes the split path."""
    groups = rod_groups(300, 4)
    namelist, output = write_input(tmp_path, "rod", groups)
    result = subprocess.run([str(BIN / "eme_run"), str(namelist)], capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    with h5py.File(output, "r") as f:
        assert f.attrs["status"] == "complete" and f.attrs["unknowns"] == 1198
        assert f["snapshots/theta"].shape == (2, 300) and f["snapshots/q"].shape == (2, 299, 1)
        assert np.allclose(f["snapshots/time"][()], [0.0, 4e-4], rtol=0, atol=1e-18)
        assert np.all(np.diff(f["entropy"][()]) > 0.0)
        energy_balance = f["balance"][:, 0]
        assert np.all(energy_balance <= 32.0)
        # The initial temperatures of the input, exactly (theta is the temperature variable's tau).
        assert np.array_equal(f["snapshots/theta"][0], groups["initial"]["theta"])


@pytest.mark.parametrize("change, option, words", [
    ({"scheme": "relaxed_dp853"}, None, "&integrator: scheme"),
    ({"tolerance": 1e-6}, None, "&integrator: tolerance"),
    ({}, "-eme_continue", "-eme_continue")])
def test_what_the_split_path_cannot_run_is_refused(tmp_path, change, option, words):
    groups = chain_groups()
    groups["integrator"].update(change)
    if "scheme" in change:
        groups["integrator"].pop("discrete_gradient")
    result, output = run_split(tmp_path, "refused", groups, 2, *([option] if option else []))
    assert result.returncode == 2, result.stderr
    assert words in result.stderr and "refused.nml" in result.stderr
    assert not list(tmp_path.glob("refused.h5*"))


def test_a_split_run_stopped_by_sigterm_keeps_its_snapshots(tmp_path):
    """One process on the split path (2000 springs), snapshots every step, a write every 3 rows
    (EME_WRITE_EVERY_ROWS): SIGTERM once the file holds a window's snapshots leaves a valid file,
    incomplete, whose snapshots are consecutive steps up to its last row."""
    groups = rod_groups(2000, 100000)
    groups["output"] = {"snapshot_every": 1}
    namelist, output = write_input(tmp_path, "long", groups)
    environment = dict(os.environ, EME_WRITE_EVERY_ROWS="3")
    process = subprocess.Popen([str(BIN / "eme_run"), str(namelist)], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True, env=environment)
    part = tmp_path / "long.h5.part"
    deadline = time.monotonic() + 300
    snapshots = 0
    while snapshots < 4 and time.monotonic() < deadline and process.poll() is None:
        time.sleep(0.2)
        try:
            with h5py.File(part, "r") as f:
                snapshots = f["snapshots/time"].shape[0] if "snapshots" in f else 0
        except (OSError, KeyError):
            snapshots = 0
    process.send_signal(signal.SIGTERM)
    stdout, stderr = process.communicate(timeout=300)
    assert process.returncode == 128 + signal.SIGTERM, stderr
    with h5py.File(output, "r") as f:
        assert f.attrs["status"] == "incomplete: interrupted by SIGTERM"
        times = f["snapshots/time"][()]
        assert times.size >= 4
        assert np.allclose(np.diff(times), 1e-4, rtol=1e-9)          # one per step, none lost or doubled
        assert times[-1] == pytest.approx(f["time"][-1], rel=1e-12)  # the last is the state the run ended at
        assert np.all(np.isfinite(f["snapshots/theta"][()]))


def test_options_cannot_loosen_the_split_step(tmp_path):
    """-snes_atol 1e3 would accept every step's predictor, the old state, as its root (0 Newton
    iterations, nothing moving, every balance kept): the input's newton_tol stands, as on the dense
    path."""
    groups = chain_groups(links=12, dimension=1, ends="fixed-fixed", steps=10, dt=0.005, newton_tol=1.0e-30)
    groups["output"] = {"snapshot_every": 10}
    result, output = run_split(tmp_path, "loose", groups, 2, "-snes_atol", "1e3")
    assert result.returncode == 0, result.stderr
    with h5py.File(output, "r") as f:
        assert np.all(f["newton_iterations"][()] >= 1)
        assert not np.array_equal(f["snapshots/q"][0], f["snapshots/q"][-1])


def test_one_rank_and_two_give_the_same_split_run(tmp_path):
    """The 300-spring rod on the split path, alone and on two ranks: the same rows and snapshots
    (the states to 1e-10 of max(1, |x|), as test_spring_chain_sparse's: Newton's rounding floor,
    16 eps |z| with |z| ~ 1e4 from the temperatures, lets the nearly still momenta, 1e-4 kg m/s,
    differ by 2e-14 between the two)."""
    groups = rod_groups(300, 6)
    groups["integrator"]["newton_tol"] = 1.0e-30          # Newton at its rounding floor on both
    groups["output"] = {"snapshot_every": 3}
    namelist, one_file = write_input(tmp_path, "one", groups)
    one = subprocess.run([str(BIN / "eme_run"), str(namelist)], capture_output=True, text=True, timeout=300)
    assert one.returncode == 0, one.stderr
    two, two_file = run_split(tmp_path, "two", groups)
    assert two.returncode == 0, two.stderr
    with h5py.File(one_file, "r") as a, h5py.File(two_file, "r") as b:
        for name in ("energy", "entropy", "lyapunov"):
            assert np.max(np.abs(a[name][()] - b[name][()])) <= 1e-12 * np.max(np.abs(a[name][()])), name
        assert np.array_equal(a["snapshots/time"][()], b["snapshots/time"][()])
        for name in ("q", "p", "gamma", "theta"):
            x, y = a[f"snapshots/{name}"][()], b[f"snapshots/{name}"][()]
            assert np.max(np.abs(x - y)) <= 1e-10 * max(1.0, np.max(np.abs(x))), name
