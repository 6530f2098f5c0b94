"""PETSc TS on the spring chain split over ranks (src/model/spring_chain/spring_chain_ts_run.F90;
docs/performance.md, "Two paths"): the chain's field f(z) = (L + K) of the exact partials and its
sparse df/dz, assembled by the ranks that own the rows, are TS's RHS function and RHS Jacobian.
- The sparse field and Jacobian are the dense model's (spring_chain_model's continuous_field, the
  engine's chain rule through the exact partials): at a small chain's initial state, on one rank
  and split over two, the field to 1e-13 and df/dz to 1e-12 of its row's largest entry; and df/dz
  is the central differences of the sparse field itself (build/tests/chain_field_probe);
- a split BDF2 run on two ranks is the dense path's ts_bdf2 run of the same input, and one rank
  and two give the same split run;
- what the split path cannot run is refused (exit 2, nothing written)."""
import os
import signal
import subprocess

import h5py
import numpy as np
import pytest

from conftest import BIN, namelist_text, run_eme
from test_spring_chain_sparse import MPIRUN, chain_groups, rod_groups
from test_split_runs import run_split, snapshot_rows, write_input

PROBE = BIN.parent / "tests" / "chain_field_probe"

FIELD_CASES = [
    dict(dimension=3, ends="fixed-free", law="thermoviscoelastic", variable="entropy"),
    dict(dimension=2, ends="fixed-fixed", law="thermoviscoelastic", variable="internal_energy"),
    dict(dimension=1, ends="fixed-fixed", law="thermoelastic", variable="temperature"),
    dict(dimension=2, ends="fixed-free", law="elastic"),
]


def probe(directory, groups, ranks):
    """chain_field_probe on `groups` over `ranks`: the sparse field at z0 and at z0 +- h_j e_j
    (rows, 2n + 1), the sparse df/dz at z0, the steps h, the dense f(z0) and df/dz(z0)."""
    groups = {key: dict(fields) for key, fields in groups.items()}
    groups["output"] = {"file": str(directory / "unused.h5")}
    namelist = directory / "probe.nml"
    namelist.write_text(namelist_text(groups))
    prefix = directory / f"probe{ranks}"
    command = [str(PROBE), str(namelist), str(prefix)]
    if ranks > 1:
        command = [*MPIRUN, "-n", str(ranks), *command]
    result = subprocess.run(command, capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    dense = np.loadtxt(f"{prefix}.dense", ndmin=2)
    h, dense_field = dense[:, 0], dense[:, 1]
    dense_jacobian = np.loadtxt(f"{prefix}.dense_jacobian", ndmin=2)
    field_rows = np.vstack([np.loadtxt(f"{prefix}.field.{rank}", ndmin=2) for rank in range(ranks)])
    jacobian_rows = np.vstack([np.loadtxt(f"{prefix}.jacobian.{rank}", ndmin=2) for rank in range(ranks)])
    total = int(jacobian_rows[:, 0].max())
    fields = np.full((2 * h.size + 1, total), np.nan)
    fields[field_rows[:, 0].astype(int), field_rows[:, 1].astype(int) - 1] = field_rows[:, 2]
    jacobian = np.full((total, total), np.nan)
    jacobian[jacobian_rows[:, 0].astype(int) - 1, jacobian_rows[:, 1].astype(int) - 1] = jacobian_rows[:, 2]
    assert not np.isnan(fields).any() and not np.isnan(jacobian).any()      # every row from one rank
    return fields, jacobian, h, dense_field, dense_jacobian


@pytest.mark.parametrize("ranks", [1, 2])
@pytest.mark.parametrize("case", FIELD_CASES, ids=lambda c: "-".join(str(v) for v in c.values()))
def test_the_sparse_field_and_jacobian_are_the_dense_models(tmp_path, case, ranks):
    groups = chain_groups(links=6, scheme="ts_bdf2", **case)
    fields, jacobian, h, dense_field, dense_jacobian = probe(tmp_path, groups, ranks)
    n = h.size
    # A 'fixed-fixed' DMDA's unused slots (beyond the n unknowns) hold nothing.
    assert np.all(fields[:, n:] == 0.0) and np.all(jacobian[n:, :n] == 0.0) and np.all(jacobian[:n, n:] == 0.0)
    field, jacobian = fields[0, :n], jacobian[:n, :n]
    assert np.max(np.abs(field - dense_field)) <= 1e-13 * np.max(np.abs(dense_field))
    # Each row against its own largest entry: a momentum row's forces and a temperature row's
    # heat rates differ by orders of magnitude.
    row_scale = np.max(np.abs(dense_jacobian), axis=1, keepdims=True)
    assert np.all(np.abs(jacobian - dense_jacobian) <= 1e-12 * row_scale)
    # Central differences of the sparse field, column j with h_j = 1e-6 max(1, |z_j|): truncation
    # h^2 f''' and rounding eps |f|/h, both below 1e-6 of the row's size (sqrt(eps), as dftd4's).
    differences = (fields[1:2 * n:2, :n] - fields[2:2 * n + 1:2, :n]).T / (2.0 * h)
    scaled_scale = np.max(np.abs(jacobian) * h, axis=1, keepdims=True)
    assert np.all(np.abs(differences - jacobian) * h <= 1e-6 * scaled_scale)


def bdf_groups(**shape):
    """A dissipative chain with BDF2 (newton_tol 1e-9: reachable at E ~ 1e3, where the TS's SNES
    residual rounds at ~1e-11; SNES runs to its absolute tolerance, no rounding floor)."""
    groups = chain_groups(**shape, scheme="ts_bdf2", steps=40, dt=0.005, newton_tol=1.0e-9)
    groups["output"] = {"snapshot_every": 10}
    return groups


def test_a_split_bdf_run_is_the_dense_paths(tmp_path):
    """The same ts_bdf2 input, dense on one process and split over two ranks. Both solve the same
    BDF2 equations, each step's Newton to |F| <= newton_tol = 1e-9 (F = shift (z - ...) - f(z),
    shift = 1.5/dt): the states differ by at most about (dt/1.5) newton_tol per step, 40 steps
    compounding to ~1e-10 at most (BDF2 is stable on this dissipative chain), and E and S by that
    times their gradients (forces ~1e2 N, 1/theta): the tolerances below, 1e-8 of max(1, |z|) in
    the state and 1e-10 relative in E and S, leave a margin of 50 or more."""
    shape = dict(links=8, dimension=2, ends="fixed-fixed")
    groups = bdf_groups(**shape)
    result, dense_file = run_eme(tmp_path, "dense", groups)
    assert result.returncode == 0, result.stderr
    result, split_file = run_split(tmp_path, "split", groups)
    assert result.returncode == 0, result.stderr
    with h5py.File(dense_file, "r") as dense, h5py.File(split_file, "r") as split:
        assert split.attrs["status"] == "complete" and split.attrs["solver_ts_type"] == "bdf"
        assert np.array_equal(split["time"][()], dense["time"][()])
        for name in ("energy", "entropy"):
            scale = np.max(np.abs(dense[name][()]))
            assert np.max(np.abs(split[name][()] - dense[name][()])) <= 1e-10 * scale, name
        # A TS run keeps no balance exactly: the split loop checks none of them (as the dense
        # path), so a step whose E moves beyond round-off does not stop it.
        assert np.max(np.abs(np.diff(split["energy"][()]))) > 1e-12 * np.max(np.abs(split["energy"][()]))
        assert np.all(split["newton_iterations"][()] >= 1)
        steps = [0, 10, 20, 30, 40]
        assert np.allclose(split["snapshots/time"][()], dense["time"][steps], rtol=0, atol=1e-14)
        for row, k in enumerate(steps):
            q, p, gamma, theta = snapshot_rows(dense["state"][k], shape["links"], shape["dimension"], True)
            for name, expected in (("q", q), ("p", p), ("gamma", gamma), ("theta", theta)):
                got = split[f"snapshots/{name}"][row]
                assert np.max(np.abs(got - expected)) <= 1e-8 * max(1.0, np.max(np.abs(expected))), (name, k)


def test_one_rank_and_two_give_the_same_split_bdf_run(tmp_path):
    """The 300-spring rod (1198 unknowns: the split path on one process too) with BDF2, alone (LU)
    and on two ranks (GMRES on block-Jacobi LU, 1e-12 relative): each step's Newton to newton_tol
    1e-9 on both, so the states agree as the dense comparison's do (1e-8 of max(1, |z|)), E and S to
    1e-10 relative."""
    groups = rod_groups(300, 6)
    groups["integrator"].update(scheme="ts_bdf2", newton_tol=1.0e-9)
    groups["output"] = {"snapshot_every": 3}
    namelist, one_file = write_input(tmp_path, "one", groups)
    one = subprocess.run([str(BIN / "eme_run"), str(namelist)], capture_output=True, text=True, timeout=300)
    assert one.returncode == 0, one.stderr
    two, two_file = run_split(tmp_path, "two", groups)
    assert two.returncode == 0, two.stderr
    with h5py.File(one_file, "r") as a, h5py.File(two_file, "r") as b:
        assert a.attrs["solver_ts_type"] == b.attrs["solver_ts_type"] == "bdf"
        assert a.attrs["solver_pc_type"] == "lu" and b.attrs["solver_pc_type"] == "bjacobi"
        for name in ("energy", "entropy"):
            assert np.allclose(b[name][()], a[name][()], rtol=1e-10, atol=0), name
        for name in ("q", "p", "gamma", "theta"):
            expected = a[f"snapshots/{name}"][()]
            assert np.max(np.abs(b[f"snapshots/{name}"][()] - expected)) <= 1e-8 * max(1.0, np.max(np.abs(expected)))
        assert np.all(np.diff(a["entropy"][()]) > 0.0)             # a dissipative run, not a still one


def test_a_rosenbrock_w_ts_runs_on_two_ranks(tmp_path):
    """`-ts_type rosw` (linearly implicit: its SNES is ksponly, which makes no line search when it
    is set up) on two ranks. Rank 0 alone described the solver for the file, and asking for the
    line search created one there: the object took a message tag of the ranks' communicator on
    rank 0 only, the ranks' later tags differed, and the first matrix product waited forever."""
    groups = bdf_groups(links=8, dimension=2, ends="fixed-fixed")
    namelist, output = write_input(tmp_path, "rosw", groups)
    process = subprocess.Popen([*MPIRUN, "-n", "2", str(BIN / "eme_run"), str(namelist), "-ts_type", "rosw"],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        _, err = process.communicate(timeout=120)
    except subprocess.TimeoutExpired:
        # mpirun and its ranks, which Open MPI puts in process groups of their own but which stay
        # in mpirun's session
        for pid in filter(str.isdigit, os.listdir("/proc")):
            try:
                if os.getsid(int(pid)) == process.pid:
                    os.kill(int(pid), signal.SIGKILL)
            except ProcessLookupError:
                pass
        process.communicate()
        pytest.fail("-ts_type rosw on two ranks did not end within 120 s")
    assert process.returncode == 0, err
    with h5py.File(output, "r") as f:
        assert f.attrs["status"] == "complete" and f.attrs["steps_completed"] == 40
        assert f.attrs["solver_ts_type"] == "rosw" and f.attrs["solver_snes_type"] == "ksponly"


@pytest.mark.parametrize("ts_type, needs", [("alpha2", "a second-order equation (TSSetI2Function)"),
                                             ("discgrad", "its own discrete-gradient formulation"),
                                             ("mimex", "an implicit part of the equations (TSSetIFunction)"),
                                             ("mprk", "slow and fast parts (TSRHSSplitSetIS)")])
@pytest.mark.parametrize("ranks", [1, 2])
def test_a_ts_type_that_needs_another_form_of_the_problem_is_refused(tmp_path, ts_type, needs, ranks):
    """PETSc is given dz/dt = f(z) and df/dz only; alpha2, discgrad and mimex crashed in their first
    step without what they need (a segmentation fault and PETSc's traceback, the file left
    'incomplete: running'), mprk stopped there. Refused at set-up, on the dense path (one process)
    and split over two ranks, with nothing written."""
    groups = bdf_groups(links=8, dimension=2, ends="fixed-fixed")
    namelist, output = write_input(tmp_path, "refused", groups)
    command = [str(BIN / "eme_run"), str(namelist), "-ts_type", ts_type]
    if ranks > 1:
        command = [*MPIRUN, "-n", str(ranks), *command]
    result = subprocess.run(command, capture_output=True, text=True, timeout=120)
    assert result.returncode == 2, result.stderr
    assert f"-ts_type {ts_type} is not allowed: PETSc's {ts_type} needs" in result.stderr and needs in result.stderr
    assert "PETSC ERROR" not in result.stderr
    assert not any(path.name.startswith(output.name) for path in tmp_path.iterdir())


@pytest.mark.parametrize("change, words", [
    ({"scheme": "cvode_bdf"}, "allowed: 'eme', 'midpoint', the relaxed schemes (relaxed_rk4, "
                              "relaxed_rk8, relaxed_dp853, relaxed_gauss6) and the PETSc TS integrators 'ts_midpoint', "
                              "'ts_bdf2', 'ts_rk4', 'ts_rk5dp'")])
def test_what_the_split_path_cannot_run_names_the_ts_integrators(tmp_path, change, words):
    groups = chain_groups(**change)
    result, output = run_split(tmp_path, "refused", groups, 2)
    assert result.returncode == 2, result.stderr
    assert words in result.stderr and "refused.nml" in result.stderr
    assert not list(tmp_path.glob("refused.h5*"))
