"""eme_run on a model split over ranks (src/run/distributed_simulation.f90, the spring chain's
sparse path): `mpirun -n P eme_run FILE.nml`, and one rank beyond the dense path's 1000 unknowns.
- A split run is the dense run: from the same input, two ranks give the dense path's per-point E, S,
  V and conserved momentum to 1e-12, and its snapshots hold the dense /state's rows to 1e-10, at
  the start, every `snapshot_every`-th step and the last;
- its file is a run file without the state in rows (no /state, /temperature), every step checked
  (/balance within its bounds) with each viscous branch's and link's entropy production >= 0;
- a chain of 1198 unknowns runs on one rank (no mpirun) on the split path;
- what the split path cannot run is refused before anything is written (exit 2);
- a split run stopped by SIGTERM keeps a valid file, marked incomplete, with its snapshots;
- -eme_continue goes on from a split file's last snapshot, on any number of ranks, and ends with
  the uninterrupted run's file (bit for bit on the same ranks), after a step budget or a SIGKILL."""
import fcntl
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


@pytest.mark.parametrize("launch", ["two-ranks", "one-process-eme-split"])
@pytest.mark.parametrize("shape", [dict(links=40, dimension=1, ends="fixed-fixed"),
                                   dict(links=12, dimension=3, ends="fixed-free")], ids=["1d-fixed-fixed", "3d-hanging"])
def test_a_split_run_is_the_dense_run(tmp_path, shape, launch):
    """The split path, on two ranks or on one process with -eme_split (below the dense path's 1000
    unknowns), against the dense path: the same rows to 1e-12 and states to 1e-10."""
    # newton_tol far below rounding: each step's Newton stops at its rounding floor on both paths.
    groups = chain_groups(**shape, steps=100, dt=0.005, newton_tol=1.0e-30)
    groups["output"] = {"snapshot_every": 25}
    result, dense_file = run_eme(tmp_path, "dense", groups, "-eme_dense")
    assert result.returncode == 0, result.stderr
    unread = "&output: snapshot_every is read by the split path only"      # the dense path says so
    assert unread in result.stderr
    if launch == "two-ranks":
        result, split_file = run_split(tmp_path, "split", groups)
    else:
        result, split_file = run_eme(tmp_path, "split", groups, "-eme_split")
    assert result.returncode == 0, result.stderr
    assert unread not in result.stderr
    assert result.stdout.count("split.h5: complete, 100/100 steps") == 1       # rank 0 alone reports
    with h5py.File(dense_file, "r") as dense, h5py.File(split_file, "r") as split:
        assert split.attrs["status"] == "complete" and split.attrs["failure_kind"] == "none"
        assert "state" not in split and "temperature" not in split
        assert np.array_equal(split["time"][()], dense["time"][()])
        # The same units on both paths (the snapshots' gamma once said 1, "viscous strain").
        columns = [name.decode() for name in dense["state_column"][()]]
        units = dict(zip(columns, dense["state"].attrs["column_units"]))
        for name, column in (("q", "x1_x"), ("p", "p1_x"), ("gamma", "gamma_1")):
            assert split[f"snapshots/{name}"].attrs["units"].decode() == units[column], name
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



@pytest.mark.parametrize("springs, scheme, options, split", [
    (16, "eme", (), False),                    # 62 unknowns: at most 64, dense
    (17, "eme", (), True),                     # 66: EME solves equations, split
    (17, "midpoint", (), True),
    (17, "relaxed_gauss6", (), True),
    (17, "ts_bdf2", (), True),
    (17, "relaxed_rk4", (), False),            # explicit: dense up to 1000 unknowns
    (17, "ts_rk4", (), False),
    (17, "eme", ("-eme_dense",), False),
    (4, "eme", ("-eme_split",), True),
], ids=["eme-62", "eme-66", "midpoint-66", "gauss6-66", "bdf2-66", "rk4-66", "ts-rk4-66", "eme-66-dense",
        "eme-14-split"])
def test_one_process_takes_the_faster_path_for_the_chain(tmp_path, springs, scheme, options, split):
    """docs/performance.md, Which path is faster: on one process a chain goes to the split path
    beyond 64 unknowns when its integrator solves equations, and stays dense up to 1000 with an
    explicit one; -eme_dense and -eme_split choose. The file says which: /snapshots or /state."""
    groups = rod_groups(springs, 4, dt=1.0e-5)
    groups["integrator"]["scheme"] = scheme
    if scheme.startswith("ts_"):
        groups["integrator"].pop("newton_tol")
    result, output = run_eme(tmp_path, "run", groups, *options)
    assert result.returncode == 0, result.stderr
    with h5py.File(output, "r") as f:
        assert f.attrs["unknowns"] == 4 * springs - 2
        assert ("snapshots" in f, "state" in f) == (split, not split)


def test_eme_dense_is_refused_with_eme_split_or_on_several_ranks(tmp_path):
    """-eme_dense asks for one process on the dense path: with -eme_split, or under mpirun, it is
    refused (exit 2, nothing written), by eme_run and by eme_ensemble."""
    groups = rod_groups(17, 4)
    namelist, output = write_input(tmp_path, "both", groups)
    both = subprocess.run([str(BIN / "eme_run"), str(namelist), "-eme_dense", "-eme_split"], capture_output=True,
                          text=True, timeout=120)
    ranks, _ = run_split(tmp_path, "both", groups, 2, "-eme_dense")
    for result in (both, ranks):
        assert result.returncode == 2 and "-eme_dense asks for the dense path" in result.stderr, result.stderr
    assert not output.exists() and not output.with_name("both.h5.part").exists()
    study = tmp_path / "study.nml"
    study.write_text(namelist.read_text() + f"&study\n  output_dir = '{tmp_path / 'study'}'\n/\n")
    refused = subprocess.run([str(BIN / "eme_ensemble"), str(study), "-eme_dense", "-eme_split"], capture_output=True,
                             text=True, timeout=120)
    assert refused.returncode == 2 and "-eme_split and -eme_dense ask for both paths" in refused.stderr, refused.stderr
    assert not (tmp_path / "study").exists()


def test_eme_split_is_refused_where_the_run_cannot_be_split(tmp_path):
    """-eme_split asks for the split path: a model that has none (the pendulum) or an integrator
    the split path lacks (CVODE) is refused with exit 2 naming the reason, nothing written."""
    pendulum = {"model": {"model_name": "double_pendulum"}, "integrator": {"scheme": "eme", "dt": 0.01, "t_end": 0.02}}
    result, path = run_eme(tmp_path, "pendulum", pendulum, "-eme_split")
    assert result.returncode == 2 and "-eme_split" in result.stderr and "dense path only" in result.stderr, \
        result.stderr
    assert not path.exists()
    chain = chain_groups(links=10, dimension=1, ends="fixed-fixed", steps=2, dt=0.005)
    chain["integrator"]["scheme"] = "cvode_bdf"
    result, path = run_eme(tmp_path, "cvode", chain, "-eme_split")
    assert result.returncode == 2 and "cvode_bdf" in result.stderr, result.stderr
    assert not path.exists()


def test_at_the_default_newton_tol_a_split_step_converges_as_a_dense_one(tmp_path):
    """A stretched, randomly bent 10-spring hanging chain in 3D (the temperature variable, newton_tol
    at its default 1e-8): a split step is accepted, as a dense one, when its residual is below the
    tolerance *and* so was the update that made it. With the residual alone, the split run accepted
    residuals creeping up to 7e-9 after two iterations, its energy balance grew to 29 ulps by step
    22 and the run stopped at step 23 (37 ulps over the bound of 32), where the dense run keeps
    0.06 ulps."""
    groups = {"model": {"model_name": "spring_chain", "links": 10, "dimension": 3},
              "initial": {"stretch": 1.5, "perturbation": "random", "amplitude": 0.2},
              "integrator": {"dt": 0.01, "t_end": 0.4}}
    result, dense_file = run_eme(tmp_path, "dense", groups, "-eme_dense")
    assert result.returncode == 0, result.stderr
    result, split_file = run_split(tmp_path, "split", groups)
    assert result.returncode == 0, result.stdout + result.stderr
    with h5py.File(dense_file, "r") as dense, h5py.File(split_file, "r") as split:
        assert split.attrs["status"] == "complete"
        energy = np.abs(split["balance"][:, 0])
        assert np.max(energy[np.isfinite(energy)]) <= 2.0
        scale = np.max(np.abs(dense["energy"][()]))
        assert np.max(np.abs(split["energy"][()] - dense["energy"][()])) <= 1e-12 * scale
        q, p, gamma, theta = snapshot_rows(dense["state"][-1], 10, 3, False)
        for name, expected in (("q", q), ("p", p), ("gamma", gamma), ("theta", theta)):
            got = split[f"snapshots/{name}"][-1]
            assert np.max(np.abs(got - expected)) <= 1e-10 * max(1.0, np.max(np.abs(expected))), name


def test_a_split_run_ended_by_a_library_error_keeps_only_states_it_reached(tmp_path):
    """-snes_error_if_not_converged turns step 2's unconverged Newton (3 iterations at most) into a
    PETSc error: the run ends with failure_kind 'library', and every snapshot in its file is a
    state the run reached, as a run stopped after step 1 has it. (The end-of-run snapshot used to
    take the last Newton iterate, stamped with step 1's time: 6e-2 off in p.)"""
    groups = chain_groups(links=8, dimension=1, ends="fixed-fixed", dt=0.03, steps=30, newton_tol=1.0e-13)
    groups["integrator"]["newton_max_iterations"] = 3
    groups["output"] = {"snapshot_every": 5}
    result, output = run_split(tmp_path, "failed", groups, 2, "-snes_error_if_not_converged")
    assert result.returncode != 0 and "PETSc failed" in result.stderr, result.stderr
    reference_groups = chain_groups(links=8, dimension=1, ends="fixed-fixed", dt=0.03, steps=1, newton_tol=1.0e-13)
    reference_groups["integrator"]["newton_max_iterations"] = 3
    reference_groups["output"] = {"snapshot_every": 1}
    result, reference_file = run_split(tmp_path, "reference", reference_groups)
    assert result.returncode == 0, result.stderr
    with h5py.File(output, "r") as f, h5py.File(reference_file, "r") as reference:
        assert f.attrs["failure_kind"] == "library" and f.attrs["status"].startswith("incomplete")
        assert np.allclose(f["time"][()], [0.0, 0.03], rtol=0, atol=1e-15)
        reached = list(reference["snapshots/time"][()])
        for row, time in enumerate(f["snapshots/time"][()]):
            k = reached.index(time)
            for name in ("q", "p", "gamma", "theta"):
                assert np.array_equal(f[f"snapshots/{name}"][row], reference[f"snapshots/{name}"][k]), (name, time)

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


@pytest.mark.parametrize("shape, option, words", [
    ({}, "-eme_continue", "-eme_continue)"),
    ({"links": 3}, None, "&model: links: a chain split over 2 ranks needs at least 2 points a rank (4); this one has 3"),
    ({}, ["-snes_type", "bogus"], "(Unable to find requested SNES type bogus (SNESSetType)); allowed:"),
    ({}, ["-ksp_type", "bogus"], "(Unable to find requested KSP type bogus (KSPSetType)); allowed:")])
def test_what_the_split_path_cannot_run_is_refused(tmp_path, shape, option, words):
    """-eme_continue without a file to continue, a chain with fewer than 2 points a rank (PETSc's
    DMDA needs its stencil width on every rank; every rank refuses alike, where one rank's PETSc
    error once left the other waiting for ever), and an unknown PETSc type, in PETSc's own words
    (once only "a library call failed with code 86"). (The integrators it cannot run: test_chain_ts.)"""
    groups = chain_groups(**shape)
    options = [option] if isinstance(option, str) else (option or [])
    result, output = run_split(tmp_path, "refused", groups, 2, *options)
    assert result.returncode == 2, result.stderr
    assert words in result.stderr and "refused.nml" in result.stderr
    assert not list(tmp_path.glob("refused.h5*"))


def test_a_refused_continuation_names_no_option_the_user_did_not_give(tmp_path):
    """-eme_continue of a complete split file is refused before any solve: no warning of unused
    PETSc options (the split solver's own -sub_pc_* defaults once showed as "nothing used")."""
    groups = chain_groups(links=8, dimension=1, ends="fixed-fixed", steps=3)
    result, _ = run_split(tmp_path, "done", groups)
    assert result.returncode == 0, result.stderr
    result, _ = run_split(tmp_path, "done", groups, 2, "-eme_continue")
    assert result.returncode == 2 and "holds a complete run" in result.stderr, result.stderr
    assert "nothing used" not in result.stderr, result.stderr


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
    status = stop_when_snapshots(process, tmp_path / "long.h5.part", 4, lambda p: p.send_signal(signal.SIGTERM))
    assert status == 128 + signal.SIGTERM
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


@pytest.mark.parametrize("launch, scheme, options, expected", [
    ("one", "eme", (), dict(snes_type="newtonls", ksp_type="preonly", pc_type="lu",
                            pc_factor_mat_ordering_type="rcm", snes_linesearch_type="basic")),
    ("two", "eme", (), dict(ksp_type="gmres", pc_type="bjacobi", sub_pc_type="lu", ksp_rtol=1e-12,
                            ksp_atol="eps |z|, z the state the step starts from", sub_pc_factor_mat_ordering_type="rcm")),
    ("two", "eme", ("-ksp_type", "bcgs", "-pc_type", "jacobi", "-ksp_atol", "1e-14", "-snes_linesearch_type", "l2"),
     dict(ksp_type="bcgs", pc_type="jacobi", ksp_atol=1e-14, snes_linesearch_type="l2")),
    ("two", "relaxed_gauss6", (), dict(ksp_type="gmres", pc_type="bjacobi", sub_pc_type="lu",
                                       ksp_atol="eps |z|/h, z the state the step starts from, h its length")),
], ids=["one-process-lu", "two-ranks-gmres", "two-ranks-options", "two-ranks-stages"])
def test_a_split_file_names_its_linear_solver(tmp_path, launch, scheme, options, expected):
    """A split run's file records the SNES and the linear solver it used, as a dense run's does
    (docs/output.md, solver_*): the documented defaults on one process and on two ranks, the
    command line's choices where it made them, and none of a choice it did not make."""
    groups = chain_groups(links=8, dimension=1, ends="fixed-fixed", scheme=scheme, steps=2)
    if launch == "one":
        result, output = run_eme(tmp_path, "run", groups, "-eme_split", *options)
    else:
        result, output = run_split(tmp_path, "run", groups, 2, *options)
    assert result.returncode == 0, result.stderr
    with h5py.File(output, "r") as f:
        attributes = {key[len("solver_"):]: value for key, value in f.attrs.items() if key.startswith("solver_")}
    for key, value in expected.items():
        got = attributes.get(key)
        got = got.decode() if isinstance(got, bytes) else got
        assert got == value, (key, got, value)
    assert attributes["newton_tol"] == 1.0e-13 and attributes["snes_max_it"] >= 1
    if launch == "one":             # a direct solve has no Krylov tolerances, and no blocks
        assert not {"ksp_rtol", "ksp_atol", "sub_pc_type"} & attributes.keys()


def test_a_newton_iterate_outside_the_domain_on_one_rank_stops_every_rank_alike(tmp_path):
    """The last spring starts 0.01 long (the others 1.1) and dt = 1 s: Newton's iterates take it
    through zero length, a domain error on rank 1 alone (its springs). Every rank must tell SNES
    alike: when rank 1 alone did, SNES took another path on it (a failed line search), the ranks'
    collectives no longer matched and the run hung. Now both ranks stop the run as one process
    does: the step halved to dt/64, then 'no root', the file kept and marked incomplete."""
    groups = chain_groups(links=12, dimension=1, ends="fixed-fixed", steps=4, dt=1.0)
    groups["initial"]["x"] = [1.1 * i for i in range(1, 12)] + [14.29]
    alone, alone_file = run_eme(tmp_path, "alone", groups, "-eme_split")
    namelist, split_file = write_input(tmp_path, "split", groups)
    # (a hang is the failure: 120 s where the run takes about 2)
    split = subprocess.run([*MPIRUN, "-n", "2", str(BIN / "eme_run"), str(namelist)], capture_output=True, text=True,
                           timeout=120)
    assert alone.returncode == split.returncode != 0, (alone.stderr, split.stderr)
    assert "no root" in split.stderr and "dt/64" in split.stderr
    with h5py.File(alone_file, "r") as a, h5py.File(split_file, "r") as b:
        for f in (a, b):        # (|R| at the last iterate differs: LU alone, GMRES on two ranks)
            assert f.attrs["status"].startswith("incomplete: step 2 (t = 2.0000 s): no root"), f.attrs["status"]
            assert f.attrs["status"].endswith("(also in steps of dt/64)")


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


def per_step_datasets(f):
    """The root datasets with one row per recorded point or per step (not the run's times)."""
    rows = (f["time"].shape[0], f["step"].shape[0])
    return sorted(name for name, item in f.items()
                  if isinstance(item, h5py.Dataset) and item.shape[:1] and item.shape[0] in rows
                  and "seconds" not in name)


def assert_continued_equals(full_file, continued_file, exact, stop_times=()):
    """The continued file holds the uninterrupted run's rows and its snapshots (plus those at the
    stops): bit for bit with `exact`, else to rounding (Newton's floor on another rank count)."""
    with h5py.File(full_file, "r") as full, h5py.File(continued_file, "r") as continued:
        assert continued.attrs["status"] == "complete", continued.attrs["status"]
        assert per_step_datasets(continued) == per_step_datasets(full)
        for name in per_step_datasets(full):
            a, b = full[name][()], continued[name][()]
            if exact or (a.dtype.kind != "f" and name != "newton_iterations"):
                assert np.array_equal(a, b, equal_nan=a.dtype.kind == "f"), name
            elif name == "newton_iterations":
                # At Newton's rounding floor a step whose start differs in the last bits (the part
                # before the stop ran on other ranks) may take one iteration more or less.
                assert np.max(np.abs(a - b)) <= 1 and np.count_nonzero(a != b) <= 0.01 * a.size, name
            elif name in ("energy", "entropy", "lyapunov"):
                assert np.max(np.abs(a - b)) <= 1e-12 * np.max(np.abs(a)), name
        # The run's totals, restored from the record with the loop's running sums: the continued
        # file's own rows add up to them.
        assert continued.attrs["newton_iterations_total"] == continued["newton_iterations"][()].sum()
        assert continued.attrs["step_rows"] == continued["step"].shape[0]
        for name in ("steps_completed", "step_rows", "newton_iterations_total", "run_figures", "balance_max_ulps"):
            a, b = np.asarray(full.attrs[name]), np.asarray(continued.attrs[name])
            if exact or (a.dtype.kind != "f" and name != "newton_iterations_total"):
                assert np.array_equal(a, b, equal_nan=a.dtype.kind == "f"), name
        assert continued.attrs.get("warnings", "") == full.attrs.get("warnings", "")
        full_times, times = full["snapshots/time"][()], continued["snapshots/time"][()]
        assert np.array_equal(np.union1d(full_times, stop_times), times)
        rows = np.searchsorted(times, full_times)
        for name in ("q", "p", "gamma", "theta"):
            a, b = full[f"snapshots/{name}"][()], continued[f"snapshots/{name}"][()][rows]
            if exact:
                assert np.array_equal(a, b), name
            else:
                assert np.max(np.abs(a - b)) <= 1e-10 * max(1.0, np.max(np.abs(a))), name


def stop_when_snapshots(process, part, count, stop, stderr=None):
    """Sends `stop` to `process` once FILE.part holds `count` snapshots; its exit status (its
    standard error appended to the list `stderr`, if given)."""
    deadline = time.monotonic() + 300
    snapshots = 0
    while snapshots < count and time.monotonic() < deadline and process.poll() is None:
        time.sleep(0.05)
        try:
            with h5py.File(part, "r") as f:
                snapshots = f["snapshots/time"].shape[0] if "snapshots" in f else 0
        except (OSError, KeyError):
            snapshots = 0
    stop(process)
    _, err = process.communicate(timeout=300)
    if stderr is not None:
        stderr.append(err)
    if process.returncode == 0:
        pytest.skip("the run ended before it could be stopped")
    return process.returncode


def with_steps(groups, steps):
    """`groups` running `steps` steps of its dt."""
    changed = {key: dict(fields) for key, fields in groups.items()}
    changed["integrator"]["t_end"] = steps * changed["integrator"]["dt"]
    return changed


@pytest.mark.parametrize("ranks, scheme", [((2, 2), "eme"), ((1, 2), "eme"), ((2, 2), "ts_midpoint"),
                                           ((2, 2), "relaxed_dp853")],
                         ids=["2-then-2-ranks", "1-then-2-ranks", "ts-midpoint", "relaxed-dp853"])
def test_a_continued_split_run_is_the_uninterrupted_run(tmp_path, ranks, scheme):
    """The 300-spring rod (1198 unknowns: split on one rank too), stopped early and continued with
    -eme_continue from its last snapshot, the one at the stop, to 30 steps further (t_end may
    change): on the same ranks the file is the uninterrupted run's, rows and snapshots bit for
    bit, plus the snapshot at the stop; on other ranks, the same to rounding. It is stopped by
    removing its lock, which every rank obeys at the same step (SIGTERM to mpirun can end in
    mpirun's SIGKILL on a loaded machine; a kill is the next test's). PETSc TS's implicit midpoint
    rule, a one-step method restarted at the snapshot, continues bit for bit too since TS's clock
    is restored with it (from 0 it differed by 2e-15 of E: TS's step to t + dt, shortened to
    land there, rounded otherwise). relaxed_dp853 (in entropy
    variables, which the snapshots hold as they are) takes its next trial step from the record: bit
    for bit too."""
    groups = rod_groups(300, 100000)
    groups["integrator"].update(scheme=scheme, newton_tol=1.0e-30)
    if scheme == "relaxed_dp853":
        groups["integrator"].update(thermo_variable="entropy", tolerance=1e-8)
        del groups["integrator"]["newton_tol"]
    groups["output"] = {"snapshot_every": 10}
    namelist, continued_file = write_input(tmp_path, "continued", groups)
    launcher = [*MPIRUN, "-n", "2"] if ranks[0] == 2 else []
    process = subprocess.Popen([*launcher, str(BIN / "eme_run"), str(namelist)], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
    part = tmp_path / "continued.h5.part"
    assert stop_when_snapshots(process, part, 3, lambda p: (tmp_path / "continued.h5.lock").unlink()) == 1
    with h5py.File(continued_file, "r") as f:      # marked incomplete, under the output's name
        assert f.attrs["status"].startswith("incomplete: the lock")
        stop_time = f["time"][-1]
        assert f["snapshots/time"][-1] == stop_time
    end = with_steps(groups, round(stop_time / 1e-4) + 30)
    full, full_file = run_split(tmp_path, "full", end, 2)
    assert full.returncode == 0, full.stderr
    resumed, _ = run_split(tmp_path, "continued", end, ranks[1], "-eme_continue")
    assert resumed.returncode == 0, resumed.stderr
    assert_continued_equals(full_file, continued_file, exact=ranks[0] == ranks[1] and scheme != "ts_midpoint",
                            stop_times=[stop_time])


def test_a_killed_split_run_continues_from_its_last_snapshot(tmp_path):
    """One process, the 300-spring rod, a snapshot every 7th step and a write every 3 rows: SIGKILL
    leaves FILE.part whose rows can run past its last snapshot; -eme_continue goes on from that
    snapshot (dropping the rows after it) and ends, 30 steps past the killed file's last row, with
    the uninterrupted run's file, bit for bit."""
    groups = rod_groups(300, 100000)
    groups["output"] = {"snapshot_every": 7}
    namelist, output = write_input(tmp_path, "killed", groups)
    environment = dict(os.environ, EME_WRITE_EVERY_ROWS="3")
    process = subprocess.Popen([str(BIN / "eme_run"), str(namelist)], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True, env=environment)
    part = tmp_path / "killed.h5.part"
    assert stop_when_snapshots(process, part, 3, lambda p: p.kill()) == -signal.SIGKILL
    with h5py.File(part, "r") as f:
        assert f.attrs["status"] == "incomplete: running"
        end = with_steps(groups, round(f["time"][-1] / 1e-4) + 30)
    namelist, full_file = write_input(tmp_path, "full", end)
    full = subprocess.run([str(BIN / "eme_run"), str(namelist)], capture_output=True, text=True, timeout=600)
    assert full.returncode == 0, full.stderr
    namelist, _ = write_input(tmp_path, "killed", end)
    resumed = subprocess.run([str(BIN / "eme_run"), str(namelist), "-eme_continue"], capture_output=True, text=True,
                             timeout=600)
    assert resumed.returncode == 0, resumed.stderr
    assert_continued_equals(full_file, output, exact=True)


def test_a_split_file_is_not_continued_on_the_dense_path(tmp_path):
    """A small chain split over two ranks cannot go on as one process (the dense path, which keeps
    its state in rows): refused, naming the file and what is allowed; the file is untouched."""
    # dt = 1 ms: this chain reaches t = 36 s (where its dampers run away and a step breaks the energy
    # balance, on one rank or two) only after several of the 1 s windows that the test waits for.
    groups = chain_groups(links=12, dimension=1, ends="fixed-fixed", steps=100000, dt=0.001)
    groups["output"] = {"snapshot_every": 10}
    namelist, output = write_input(tmp_path, "small", groups)
    process = subprocess.Popen([*MPIRUN, "-n", "2", str(BIN / "eme_run"), str(namelist)], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
    assert stop_when_snapshots(process, tmp_path / "small.h5.part", 2,
                               lambda p: (tmp_path / "small.h5.lock").unlink()) == 1
    before = output.read_bytes()      # marked incomplete, under the output's name
    namelist = tmp_path / "small.nml"
    refused = subprocess.run([str(BIN / "eme_run"), str(namelist), "-eme_continue"], capture_output=True, text=True,
                             timeout=120)
    assert refused.returncode == 2, refused.stderr
    assert "split over ranks" in refused.stderr and "mpirun -n P" in refused.stderr
    assert output.read_bytes() == before


def test_a_lock_removed_during_a_split_run_stops_it(tmp_path):
    """One process on the split path: removing FILE.lock while it runs stops it at its next step,
    exit status 1; no other writer holds the lock, so the run takes it again and writes its file
    once more, marked incomplete, under the output's name (as the dense path does,
    test_file_integrity), its last snapshot the state it stopped at. (Before, the check passed a
    nested function where a logical was asked, and the run went on.)"""
    groups = rod_groups(300, 100000)
    groups["output"] = {"snapshot_every": 50}
    namelist, output = write_input(tmp_path, "locked", groups)
    process = subprocess.Popen([str(BIN / "eme_run"), str(namelist)], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
    part = tmp_path / "locked.h5.part"
    stderr = []
    status = stop_when_snapshots(process, part, 2, lambda p: (tmp_path / "locked.h5.lock").unlink(), stderr)
    assert status == 1
    assert "took the lock again" in stderr[0], stderr[0]
    assert not part.exists()
    with h5py.File(output, "r") as f:
        assert f.attrs["status"] == f"incomplete: the lock {output}.lock was removed while the run wrote"
        assert f["snapshots/time"][-1] == f["time"][-1]


def test_a_lock_taken_by_a_second_writer_stops_a_split_run_which_leaves_it_alone(tmp_path):
    """Two ranks: FILE.lock is replaced by another process's, held, while the run writes.
    The run stops at its next step (exit 1), names the other holder, writes nothing more (FILE.part
    stays as its last window made it, a valid file of complete snapshots) and leaves the other's
    lock as it is."""
    # dt = 1 ms: this chain reaches t = 36 s (where its dampers run away and a step breaks the energy
    # balance, on one rank or two) only after several of the 1 s windows that the test waits for.
    groups = chain_groups(links=12, dimension=1, ends="fixed-fixed", steps=100000, dt=0.001)
    groups["output"] = {"snapshot_every": 10}
    namelist, output = write_input(tmp_path, "taken", groups)
    process = subprocess.Popen([*MPIRUN, "-n", "2", str(BIN / "eme_run"), str(namelist)], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
    part = tmp_path / "taken.h5.part"
    lock = tmp_path / "taken.h5.lock"
    holder = "process 1 on host elsewhere\n"
    with open(tmp_path / "other.lock", "w") as other:
        def take_the_lock(process):
            # One rename replaces the lock file with the other writer's, held: no moment without a lock
            # file, in which the run could take the lock again itself.
            other.write(holder)
            other.flush()
            fcntl.flock(other, fcntl.LOCK_EX | fcntl.LOCK_NB)
            os.rename(tmp_path / "other.lock", lock)
        stderr = []
        status = stop_when_snapshots(process, part, 2, take_the_lock, stderr)
        assert lock.read_text() == holder
    assert status == 1
    assert "was replaced" in stderr[0] and "process 1 on host elsewhere" in stderr[0], stderr[0]
    assert "writes nothing more" in stderr[0], stderr[0]
    assert not output.exists()
    with h5py.File(part, "r") as f:
        assert f.attrs["status"].startswith("incomplete")
        assert f["snapshots/time"].shape[0] >= 2


def test_a_chain_file_holds_its_metric_scales_as_one_row_per_spring(tmp_path):
    """A chain of 13 springs (fixed-fixed, 12 masses) of unlike natural lengths and heat capacities,
    EME in the entropy: both paths write the discrete gradients' metric scales as one attribute
    `metric_scale` of a row per spring, (l0_a^2, 1 m, Cap_a) with Cap_a = (1 + beta_v) c0_a
    (docs/formulation.md sections 3 and 5), not 26 attributes metric_scale_spring<a>[_units]; a
    double pendulum keeps its two named ones."""
    groups = chain_groups(links=12, dimension=1, ends="fixed-fixed", variable="entropy", steps=1, dt=0.005)
    lengths = [1.0 + 0.01 * a for a in range(13)]
    capacities = [10.0 + a for a in range(13)]
    groups["model"].update(natural_length=lengths, heat_capacity=capacities, span=1.1 * sum(lengths))
    expected = np.column_stack([np.square(lengths), np.ones(13), 1.5 * np.array(capacities)])
    for name, run in (("dense", lambda: run_eme(tmp_path, "dense", groups)),
                      ("split", lambda: run_split(tmp_path, "split", groups))):
        result, output = run()
        assert result.returncode == 0, result.stderr
        with h5py.File(output, "r") as f:
            assert f.attrs["status"] == "complete", name
            assert np.allclose(f.attrs["metric_scale"], expected, rtol=1e-15, atol=0.0), name
            assert not [key for key in f.attrs if key.startswith("metric_scale_spring")], name
    result, output = run_eme(tmp_path, "pendulum", {"integrator": {"dt": 0.01, "t_end": 0.01}})
    assert result.returncode == 0, result.stderr
    with h5py.File(output, "r") as f:
        assert "metric_scale" not in f.attrs
        assert f.attrs["metric_scale_spring1"].shape == (2,) and f.attrs["metric_scale_spring2"].shape == (3,)
