"""The relaxed Runge-Kutta family on the chain split over ranks (src/model/spring_chain/
spring_chain_relaxed_run.F90; docs/integrators.md, "The relaxed family on the split chain").
- From the same state the split relaxed_rk4 (and relaxed_rk8) on 2 ranks takes the dense path's steps: the update
  P(z + gamma d) and the time reached, t + gamma h, are the same (relaxation in time on both paths;
  the last step lands on t_end), so the times, states, E, S and gamma agree step by step to
  rounding;
- 1 and 2 ranks give the same run (a chain beyond the dense path's 1000 unknowns, split on one rank);
- every step keeps E to round-off (the run's own balance check, in ulps of its terms), the conserved
  angular momentum, S_{n+1} - S_n = gamma e_S (the entropy identity of entropy variables) with
  e_S >= 0, and every viscous branch's and link's production >= 0;
- a step without a relaxation root is halved (recursively, counted in /halved_steps and the
  summary's halved_steps), the run still lands on t_end, and the complete file carries the dense
  path's accuracy warning;
- relaxed_rk4 converges at its order 4 on the split path;
- relaxed_dp853 chooses its steps (DOP853's error norm summed over the ranks): its rows are its
  accepted steps, it lands on t_end and on &output interval's times, its error falls with the
  tolerance against a tight reference, 1 and 2 ranks agree, and it keeps every balance;
- relaxed_gauss6's implicit stages are solved together by SNES over the split state
  (spring_chain_stage_solve): from the same state its steps are the dense path's, 1 and 2 ranks
  agree, it converges at its order 6, it stays stable with 3 Newton iterations a step on a rod of
  1000 springs at a step where relaxed_rk4 must halve, and a run stopped by its step budget and
  continued is the uninterrupted run, bit for bit."""
import h5py
import numpy as np
import pytest

from conftest import run_eme
from test_spring_chain_sparse import chain_groups, rod_groups
from test_split_runs import assert_continued_equals, run_split


def relaxed_chain(scheme="relaxed_rk4", variable="temperature", dt=0.005, steps=40, **shape):
    """chain_groups' chain; in 3D the masses also move across its plane (p_y = 0.3 cos i N s), so that
    J_z, which gravity along z keeps, is not zero."""
    groups = chain_groups(scheme=scheme, variable=variable, dt=dt, steps=steps, **shape)
    if scheme == "relaxed_gauss6":
        # Implicit stages: Newton to its rounding floor on both paths (below it no |R| is reached).
        groups["integrator"]["newton_tol"] = 1.0e-30
    else:
        del groups["integrator"]["newton_tol"]              # explicit stages: no Newton
    if shape.get("dimension") == 3:
        groups["initial"]["p"] = [v for i in range(1, shape["links"] + 1) for v in (0.0, 0.3 * np.cos(i), 0.0)]
    groups["output"] = {"snapshot_every": 1}
    return groups


def dense_rows(state, links, dimension):
    """q, p (masses x dimension), gamma and tau of a hanging thermoviscoelastic chain's /state row."""
    rows = state[:links * (2 * dimension + 2)].reshape(links, 2 * dimension + 2)
    return rows[:, :dimension], rows[:, dimension:2 * dimension], rows[:, 2 * dimension], rows[:, 2 * dimension + 1]


@pytest.mark.parametrize("scheme, variable, tau", [("relaxed_rk4", "temperature", "theta"),
                                                   ("relaxed_rk8", "internal_energy", "internal_energy"),
                                                   ("relaxed_gauss6", "entropy", "entropy")])
def test_split_relaxed_steps_are_the_dense_ones(tmp_path, scheme, variable, tau):
    """A hanging 3D chain of 12 unlike springs (J_z kept), dt = 5 ms, 40 steps; the snapshots hold
    tau in the run's variable (the steps run in entropy variables).

    Agreement to 1e-11 relative (states, E, S) and 1e-9 in gamma: both paths compute the same stages
    and root; the ranks' sums and the projection's Gram form change the rounding only, and gamma is
    resolved to the rounding floor of r(gamma) over its slope (about 1e-11 at these steps), which
    moves the state by gamma's error times |d|."""
    links, dimension, steps = 12, 3, 40
    groups = relaxed_chain(scheme=scheme, variable=variable, links=links, dimension=dimension)
    result, dense_file = run_eme(tmp_path, "dense", groups, "-eme_dense")
    assert result.returncode == 0, result.stderr
    result, split_file = run_split(tmp_path, "split", groups, 2)
    assert result.returncode == 0, result.stderr
    with h5py.File(dense_file, "r") as dense, h5py.File(split_file, "r") as split:
        assert split.attrs["status"] == "complete" and split.attrs["scheme"] == scheme
        assert "state" not in split
        # Relaxation in time on both paths: a step of h reaches t + gamma h, the last lands on t_end.
        gamma_dense = dense["relaxation_gamma"][()]
        gamma_split = split["relaxation_gamma"][()]
        rows = len(dense["time"])
        assert len(split["time"]) == rows and split["time"][-1] == dense["time"][-1] == 0.005 * steps
        assert np.allclose(dense["time"][1:rows - 1], 0.005 * np.cumsum(gamma_dense[:rows - 2]), rtol=0, atol=1e-15)
        # (the times differ by the sums of h times gamma's rounding: 2.9e-14 measured)
        assert np.max(np.abs(split["time"][()] - dense["time"][()])) <= 1e-12
        # Step by step the same states, the landing step among them.
        compared = range(1, rows)
        assert np.max(np.abs(gamma_split - gamma_dense)) <= 1e-9
        if scheme == "relaxed_rk4":
            assert np.max(np.abs(gamma_dense - 1.0)) > 1e-8     # gamma is no 1 here: the relaxation acts
        if scheme == "relaxed_gauss6":
            assert np.all(split["newton_iterations"][()] >= 2)   # each step's stages took Newton updates
            assert split.attrs["solver_name"].startswith("PETSc SNES")
        for name in ("energy", "entropy"):
            expected = dense[name][()]
            assert np.max(np.abs(split[name][()] - expected)) <= 1e-11 * np.max(np.abs(expected)), name
        for n in compared:
            q, p, gamma, tau_values = dense_rows(dense["state"][n], links, dimension)
            for name, expected in (("q", q), ("p", p), ("gamma", gamma), (tau, tau_values)):
                got = split[f"snapshots/{name}"][n]
                assert np.max(np.abs(got - expected)) <= 1e-11 * max(1.0, np.max(np.abs(expected))), (name, n)
        # Every step: E to round-off (the run's check, in ulps of E's terms), J_z kept, S rising by
        # gamma e_S >= 0 exactly, every branch's and link's production >= 0.
        balance = split["balance"][()]
        assert np.all(balance[np.isfinite(balance)] <= 32.0)
        energy = split["energy"][()]
        assert np.max(np.abs(energy - energy[0])) <= 1e-13 * np.max(np.abs(energy))
        jz = split["angular_momentum"][:, 2]
        assert abs(jz[0]) > 0.1
        assert np.max(np.abs(jz - jz[0])) <= 1e-12 * max(1.0, np.max(np.abs(split["angular_momentum"][()])))
        increments = np.diff(split["entropy"][()])
        production = split["entropy_production"][()]
        assert np.all(production >= 0.0) and np.all(increments > 0.0)
        assert np.max(np.abs(increments - production)) <= 1e-12 * np.max(np.abs(split["entropy"][()]))
        assert np.all(split["min_viscous_production"][()] >= 0.0)
        assert np.all(split["min_link_production"][()] >= 0.0)
        assert split["halved_steps"][()].sum() == 0 and "warnings" not in split.attrs


def test_split_relaxed_rk4_lands_on_the_output_times_as_the_dense_path(tmp_path):
    """relaxed_rk4 at a fixed dt with &output interval: a relaxed step of h reaches t + gamma h, and
    the one that would pass an output time is redone to land on it, so the rows are the output times
    and each row's state is the dense path's run of the same input (1e-11 of each field's size)."""
    links, dimension = 12, 3
    groups = relaxed_chain(links=links, dimension=dimension)
    groups["output"] = {"interval": 0.05}
    result, dense_file = run_eme(tmp_path, "dense", groups)
    assert result.returncode == 0, result.stderr
    result, split_file = run_split(tmp_path, "split", groups, 2)
    assert result.returncode == 0, result.stderr
    with h5py.File(dense_file, "r") as dense, h5py.File(split_file, "r") as split:
        assert split.attrs["status"] == "complete"
        assert np.allclose(split["time"][()], 0.05 * np.arange(5), rtol=0, atol=1e-15)
        assert np.allclose(dense["time"][()], 0.05 * np.arange(5), rtol=0, atol=1e-15)
        assert np.allclose(split["snapshots/time"][()], 0.05 * np.arange(5), rtol=0, atol=1e-15)
        for n in range(1, 5):
            q, p, gamma, theta = dense_rows(dense["state"][n], links, dimension)
            for name, expected in (("q", q), ("p", p), ("gamma", gamma), ("theta", theta)):
                got = split[f"snapshots/{name}"][n]
                assert np.max(np.abs(got - expected)) <= 1e-11 * max(1.0, np.max(np.abs(expected))), (name, n)


def test_a_step_whose_relaxed_time_would_pass_t_end_is_redone_to_land_on_it(tmp_path):
    """The hanging chain at dt = 50 ms, whose third step has gamma > 1 (1.0014 measured): with
    t_end placed between t_2 + 1.01 dt (so the step is no landing step from the start) and
    t_2 + (gamma + 0.01) dt (so its relaxed time passes t_end, or leaves less than 1 % of dt
    before it), the step is redone as the landing step of t_end - t_2 > dt, as on the dense path:
    three steps, the last longer than dt, ending on t_end exactly (not a third step of gamma dt
    and a sliver after it)."""
    dt = 0.05
    groups = relaxed_chain(dt=dt, steps=20, links=12, dimension=3)
    result, probe_file = run_eme(tmp_path, "probe", groups)
    assert result.returncode == 0, result.stderr
    with h5py.File(probe_file, "r") as f:
        t_2, gamma_3 = f["time"][2], f["relaxation_gamma"][2]
    assert gamma_3 > 1.0 + 1e-4, gamma_3
    t_end = t_2 + 0.5 * (1.01 + gamma_3 + 0.01) * dt
    groups["integrator"]["t_end"] = t_end
    result, dense_file = run_eme(tmp_path, "dense", groups)
    assert result.returncode == 0, result.stderr
    result, split_file = run_split(tmp_path, "split", groups, 2)
    assert result.returncode == 0, result.stderr
    with h5py.File(split_file, "r") as split, h5py.File(dense_file, "r") as dense:
        times = split["time"][()]
        assert len(times) == 4 and times[-1] == t_end, times
        assert times[3] - times[2] > 1.01 * dt
        assert len(dense["time"]) == 4 and abs(dense["time"][2] - times[2]) <= 1e-14


@pytest.mark.parametrize("scheme", ["relaxed_rk4", "relaxed_gauss6"])
def test_one_and_two_ranks_give_the_same_run(tmp_path, scheme):
    """300 springs of the rod family (1198 unknowns: split on one rank too), entropy variable,
    dt = 2e-5 s (below RK4's stability limit there), 20 steps; the sums over the ranks are added in
    another order (and relaxed_gauss6's linear solves differ: LU on one rank, GMRES on block-Jacobi
    LU on two), nothing else differs. Both gammas are roots to r's rounding floor; at these short
    steps (|d| about 1e-6 |z|) r is so flat in gamma that the floor resolves gamma only to about 1e-9
    (measured: 2.8e-9 apart with relaxed_rk4), and the states they give agree to 1e-13 of each
    field's size."""
    groups = rod_groups(300, 20, dt=2.0e-5)
    groups["integrator"].update({"scheme": scheme, "thermo_variable": "entropy"})
    if scheme == "relaxed_gauss6":
        groups["integrator"]["newton_tol"] = 1.0e-30
    else:
        del groups["integrator"]["newton_tol"]
    groups["output"] = {"snapshot_every": 5}
    one, one_file = run_split(tmp_path, "one", groups, 1)
    assert one.returncode == 0, one.stderr
    two, two_file = run_split(tmp_path, "two", groups, 2)
    assert two.returncode == 0, two.stderr
    with h5py.File(one_file, "r") as a, h5py.File(two_file, "r") as b:
        assert a.attrs["unknowns"] == 1198 and a.attrs["status"] == b.attrs["status"] == "complete"
        for name in ("energy", "entropy"):
            assert np.allclose(b[name][()], a[name][()], rtol=1e-12, atol=0), name
        assert np.allclose(b["relaxation_gamma"][()], a["relaxation_gamma"][()], rtol=0, atol=1e-8)
        for name in ("q", "p", "gamma", "theta", "entropy"):
            expected = a[f"snapshots/{name}"][()]
            assert np.max(np.abs(b[f"snapshots/{name}"][()] - expected)) <= 1e-11 * max(1.0, np.max(np.abs(expected))), name
        energy = b["energy"][()]
        assert np.max(np.abs(energy - energy[0])) <= 1e-13 * np.max(np.abs(energy))
        assert np.all(np.diff(b["entropy"][()]) > 0.0)


def test_a_step_without_a_root_is_halved_and_the_run_lands_on_t_end(tmp_path):
    """The 12-spring chain at dt = 0.1 s: some steps find no relaxation root (or a stage leaves the
    domain) and are halved, recursively, as on the dense path; each row is at the time its step
    reached, the last on t_end; every step keeps E, and the complete file says that dt was too long
    for relaxed_rk4's accuracy."""
    steps = 10
    groups = relaxed_chain(dt=0.1, steps=steps, links=12, dimension=3)
    groups["output"] = {"snapshot_every": 5}
    result, split_file = run_split(tmp_path, "coarse", groups, 2)
    assert result.returncode == 0, result.stderr
    with h5py.File(split_file, "r") as f:
        assert f.attrs["status"] == "complete"
        halved = f["halved_steps"][()]
        assert halved.sum() > 0, "no step was halved"
        assert np.array_equal(f["rejected_steps"][()], halved)
        times = f["time"][()]
        assert times[-1] == 0.1 * steps and np.all(np.diff(times) > 0.0)
        balance = f["balance"][()]
        assert np.all(balance[np.isfinite(balance)] <= 32.0)
        assert f"{int(halved.sum())} trial steps rejected ({int(halved.sum())} halved)" in f.attrs["warnings"]
        assert "dt = 0.1 s is too long for relaxed_rk4's accuracy" in f.attrs["warnings"]
    assert "trial steps rejected" in result.stdout + result.stderr



def test_split_relaxed_rk4_converges_at_order_four(tmp_path):
    """The 12-spring fixed-fixed chain of chain_groups (1D, unlike springs, a temperature gradient)
    to 0.4 s on two ranks with relaxed_rk4 at 50, 100 and 200 steps against relaxed_rk8 at 400
    steps (whose own error, 1e-11 between 100 and 200 steps, is below the rk4 errors): the error of
    the final state max(|q|, |p|, |gamma|, |theta|/300) falls by 2^4 per halving (measured 2.33e-6,
    1.43e-7, 8.9e-9: orders 4.02 and 4.02; asserted >= 3.7). The relaxation's root is found to
    the rounding of E only, on an r(gamma) whose slope falls like |d|^2 with the step: its
    rounding error grows as the step shrinks and accumulates over the steps (rk8 at 3200 steps
    differs from 1600 by 7e-10), so the steps are not refined further."""
    def final_state(name, scheme, steps):
        groups = chain_groups(links=12, dimension=1, ends="fixed-fixed", scheme=scheme, dt=0.4 / steps, steps=steps)
        del groups["integrator"]["newton_tol"]
        result, output = run_split(tmp_path, name, groups)
        assert result.returncode == 0, result.stderr
        with h5py.File(output, "r") as f:
            assert f.attrs["status"] == "complete" and f["snapshots/time"][-1] == pytest.approx(0.4, rel=1e-14)
            return np.concatenate([f["snapshots/q"][-1].ravel(), f["snapshots/p"][-1].ravel(),
                                   f["snapshots/gamma"][-1], f["snapshots/theta"][-1] / 300.0])

    reference = final_state("reference", "relaxed_rk8", 400)
    errors = [np.max(np.abs(final_state(f"rk4_{steps}", "relaxed_rk4", steps) - reference)) for steps in (50, 100, 200)]
    orders = [np.log2(errors[k] / errors[k + 1]) for k in range(2)]
    assert errors[-1] < 1e-7 and min(orders) >= 3.7, (errors, orders)


def test_split_relaxed_gauss6_converges_at_order_six(tmp_path):
    """The chain of the order-4 test to 0.4 s on two ranks with relaxed_gauss6 at 10, 20 and 40 steps
    (Newton to its rounding floor) against relaxed_rk8 at 400 steps: the error of the final state
    falls by 2^6 per halving (measured 2.26e-6, 3.70e-8, 5.85e-10: orders 5.93 and 5.98; asserted
    >= 5.5)."""
    def final(name, scheme, steps):
        groups = chain_groups(links=12, dimension=1, ends="fixed-fixed", scheme=scheme, dt=0.4 / steps, steps=steps)
        if scheme == "relaxed_gauss6":
            groups["integrator"]["newton_tol"] = 1.0e-30
        else:
            del groups["integrator"]["newton_tol"]
        result, output = run_split(tmp_path, name, groups)
        assert result.returncode == 0, result.stderr
        with h5py.File(output, "r") as f:
            assert f.attrs["status"] == "complete" and f["snapshots/time"][-1] == pytest.approx(0.4, rel=1e-14)
            assert f["halved_steps"][()].sum() == 0
            return final_state(f)

    reference = final("reference", "relaxed_rk8", 400)
    errors = [np.max(np.abs(final(f"gauss6_{steps}", "relaxed_gauss6", steps) - reference)) for steps in (10, 20, 40)]
    orders = [np.log2(errors[k] / errors[k + 1]) for k in range(2)]
    assert errors[-1] < 5e-9 and min(orders) >= 5.5, (errors, orders)


def test_relaxed_gauss6_holds_where_relaxed_rk4_must_halve(tmp_path):
    """The rod family at 1000 springs on two ranks, dt = 1 ms: 87 times relaxed_rk4's stability limit
    there as postprocess/chain_study.py's rk4_limits estimates it (the waves', 1.15e-5 s). relaxed_rk4
    finishes only by halving its steps (measured: 1243 halvings in 11 steps to 10 ms); relaxed_gauss6, A-stable,
    takes every step whole with 3 Newton iterations of its stages and keeps every balance: E to
    round-off, S rising by gamma e_S, every branch's and link's production >= 0."""
    groups = rod_groups(1000, 10, dt=1.0e-3)
    groups["integrator"].update({"scheme": "relaxed_gauss6", "thermo_variable": "entropy", "newton_tol": 1.0e-30})
    result, output = run_split(tmp_path, "gauss6", groups)
    assert result.returncode == 0, result.stderr
    with h5py.File(output, "r") as f:
        assert f.attrs["status"] == "complete" and "warnings" not in f.attrs
        assert f["halved_steps"][()].sum() == 0
        assert np.all(f["newton_iterations"][()] <= 4)
        energy = f["energy"][()]
        assert np.max(np.abs(energy - energy[0])) <= 1e-13 * np.max(np.abs(energy))
        increments = np.diff(f["entropy"][()])
        assert np.all(increments > 0.0)
        assert np.max(np.abs(increments - f["entropy_production"][()])) <= 1e-12 * np.max(np.abs(f["entropy"][()]))
        assert np.all(f["min_viscous_production"][()] >= 0.0) and np.all(f["min_link_production"][()] >= 0.0)
    groups["integrator"]["scheme"] = "relaxed_rk4"
    del groups["integrator"]["newton_tol"]
    result, output = run_split(tmp_path, "rk4", groups)
    assert result.returncode == 0, result.stderr
    with h5py.File(output, "r") as f:
        assert f["halved_steps"][()].sum() > 100


@pytest.mark.parametrize("scheme, output", [("relaxed_gauss6", {"snapshot_every": 1}),
                                            ("relaxed_rk4", {"interval": 0.05})])
def test_a_continued_relaxed_run_is_the_uninterrupted_run(tmp_path, scheme, output):
    """The 12-spring chain on two ranks, stopped by its step budget (15 of about 40 steps) and
    continued with -eme_continue, ends with the uninterrupted run's file bit for bit: relaxed_gauss6's
    stages' Newton starts from f(z) alone, so nothing but the snapshot and its time are needed;
    relaxed_rk4 with &output interval goes on from the last output time before the stop (0.05 s),
    its steps landing on the output times again."""
    groups = relaxed_chain(scheme=scheme, variable="entropy", links=12, dimension=1, ends="fixed-fixed")
    groups["output"] = output
    stopped = {key: dict(fields) for key, fields in groups.items()}
    stopped["integrator"]["max_steps"] = 15
    result, continued_file = run_split(tmp_path, "continued", stopped)
    assert result.returncode == 3, result.stderr
    full, full_file = run_split(tmp_path, "full", groups)
    assert full.returncode == 0, full.stderr
    resumed, _ = run_split(tmp_path, "continued", groups, 2, "-eme_continue")
    assert resumed.returncode == 0, resumed.stderr
    assert_continued_equals(full_file, continued_file, exact=True)


def test_a_continued_fixed_step_relaxed_run_keeps_its_warning_record(tmp_path):
    """relaxed_rk4 at dt = 0.1 s on the 8-spring fixed-fixed chain halves steps (no tolerance bounds
    them, so the file warns). Stopped after 7 steps and continued, the file is the uninterrupted
    run's, its warning too: the halvings and the largest |gamma - 1| before the stop are in the
    resume record (once only relaxed_dp853's were, and the continued file counted 3 halvings of 6)."""
    groups = chain_groups(links=8, dimension=1, ends="fixed-fixed", scheme="relaxed_rk4", variable="entropy",
                          dt=0.1, steps=10)
    del groups["integrator"]["newton_tol"]
    groups["output"] = {"snapshot_every": 2}
    stopped = {key: dict(fields) for key, fields in groups.items()}
    stopped["integrator"]["max_steps"] = 7
    result, continued_file = run_split(tmp_path, "continued", stopped)
    assert result.returncode == 3, result.stderr
    with h5py.File(continued_file, "r") as f:
        stop_time = f["snapshots/time"][-1]          # the state at the stop, between two snapshots
    full, full_file = run_split(tmp_path, "full", groups)
    assert full.returncode == 0, full.stderr
    resumed, _ = run_split(tmp_path, "continued", groups, 2, "-eme_continue")
    assert resumed.returncode == 0, resumed.stderr
    assert_continued_equals(full_file, continued_file, exact=True, stop_times=[stop_time])
    with h5py.File(full_file, "r") as f:
        assert "halved" in f.attrs["warnings"], f.attrs.get("warnings")


def dp853_chain(tolerance, t_end=0.4):
    """The 12-spring fixed-fixed chain of the order test, relaxed_dp853 at `tolerance` (its first trial
    step 0.01 s), in entropy variables."""
    groups = chain_groups(links=12, dimension=1, ends="fixed-fixed", scheme="relaxed_dp853", variable="entropy",
                          dt=0.01, steps=round(t_end / 0.01))
    del groups["integrator"]["newton_tol"]
    groups["integrator"]["tolerance"] = tolerance
    return groups


def final_state(f):
    return np.concatenate([f["snapshots/q"][-1].ravel(), f["snapshots/p"][-1].ravel(), f["snapshots/gamma"][-1],
                           f["snapshots/theta"][-1] / 300.0])


def test_split_relaxed_dp853_chooses_its_steps_and_meets_its_tolerance(tmp_path):
    """relaxed_dp853 on two ranks (DOP853's error norm summed over the ranks, its controller) to 0.4 s
    at tolerances 1e-5 and 1e-9, against relaxed_rk8 at 400 steps (the order test's reference, its
    own error about 1e-11). Each accepted step is a row at the time it reached, the last on t_end
    exactly; the error falls with the tolerance (measured 2.2e-5 and 5.3e-9, a factor 4200 for
    1e4 in tolerance, with 6 and 14 steps) and stays within 100 tolerances; every step keeps E to
    round-off and S_{n+1} - S_n = gamma e_S >= 0, every branch's and link's production >= 0."""
    reference_groups = chain_groups(links=12, dimension=1, ends="fixed-fixed", scheme="relaxed_rk8", dt=0.001,
                                    steps=400)
    del reference_groups["integrator"]["newton_tol"]
    result, reference_file = run_split(tmp_path, "reference", reference_groups)
    assert result.returncode == 0, result.stderr
    with h5py.File(reference_file, "r") as f:
        reference = final_state(f)
    errors, steps = [], []
    for tolerance in (1e-5, 1e-9):
        result, output = run_split(tmp_path, f"dp853_{tolerance:g}", dp853_chain(tolerance))
        assert result.returncode == 0, result.stderr
        with h5py.File(output, "r") as f:
            assert f.attrs["status"] == "complete" and "warnings" not in f.attrs
            times = f["time"][()]
            assert times[-1] == 0.4 and np.all(np.diff(times) > 0.0)
            assert np.ptp(np.diff(times[:-1])) > 0.0, "the steps are all alike: the controller chose nothing"
            errors.append(np.max(np.abs(final_state(f) - reference)))
            steps.append(len(times) - 1)
            energy = f["energy"][()]
            assert np.max(np.abs(energy - energy[0])) <= 1e-13 * np.max(np.abs(energy))
            balance = f["balance"][()]
            assert np.all(balance[np.isfinite(balance)] <= 32.0)
            increments, production = np.diff(f["entropy"][()]), f["entropy_production"][()]
            assert np.all(production >= 0.0)
            assert np.max(np.abs(increments - production)) <= 1e-12 * np.max(np.abs(f["entropy"][()]))
            assert np.all(f["min_viscous_production"][()] >= 0.0) and np.all(f["min_link_production"][()] >= 0.0)
    assert errors[0] <= 100 * 1e-5 and errors[1] <= 100 * 1e-9, errors
    assert errors[1] < errors[0] / 100 and steps[1] > steps[0], (errors, steps)


def test_split_relaxed_dp853_lands_on_the_output_times(tmp_path):
    """With &output interval the adaptive steps land on every output time (a step that would pass
    one is shortened to it), and the rows are those times."""
    groups = dp853_chain(1e-7, t_end=0.3)
    groups["output"] = {"interval": 0.05}
    result, output = run_split(tmp_path, "interval", groups)
    assert result.returncode == 0, result.stderr
    with h5py.File(output, "r") as f:
        assert f.attrs["status"] == "complete"
        assert np.allclose(f["time"][()], 0.05 * np.arange(7), rtol=0, atol=1e-15)
        energy = f["energy"][()]
        assert np.max(np.abs(energy - energy[0])) <= 1e-13 * np.max(np.abs(energy))


def test_split_relaxed_dp853_on_one_and_two_ranks(tmp_path):
    """The 300-spring rod (1198 unknowns: split on one rank too) at tolerance 1e-8 for 4e-4 s on one
    rank and on two: the ranks' sums (the relaxation's and the error norm's) are added in another
    order, nothing else differs. The error estimate sum_i e5_i k_i cancels the stages to about 1e-7
    of their size, so the rounding of gamma (resolved only to about 1e-9 at these short steps, see
    the relaxed_rk4 test above) moves the chosen steps by about 1e-7 relatively (measured 3e-7):
    the same number of steps, their times to 1e-5, and the states at t_end, where both land, to
    1e-10 (measured 2.7e-12 in p, 1.4e-14 in q, 6e-14 in theta; E per step 8e-16)."""
    groups = rod_groups(300, 20, dt=2.0e-5)
    groups["integrator"].update({"scheme": "relaxed_dp853", "thermo_variable": "entropy", "tolerance": 1e-8})
    del groups["integrator"]["newton_tol"]
    one, one_file = run_split(tmp_path, "one", groups, 1)
    assert one.returncode == 0, one.stderr
    two, two_file = run_split(tmp_path, "two", groups, 2)
    assert two.returncode == 0, two.stderr
    with h5py.File(one_file, "r") as a, h5py.File(two_file, "r") as b:
        assert a.attrs["unknowns"] == 1198 and a.attrs["status"] == b.attrs["status"] == "complete"
        assert len(a["time"]) == len(b["time"]) > 4 and a["time"][-1] == b["time"][-1] == 4e-4
        assert np.allclose(b["time"][()], a["time"][()], rtol=1e-5, atol=0)
        for name in ("energy", "entropy"):
            assert np.allclose(b[name][()], a[name][()], rtol=1e-10, atol=0), name
        for name in ("q", "p", "gamma", "theta", "entropy"):
            expected = a[f"snapshots/{name}"][-1]
            difference = np.max(np.abs(b[f"snapshots/{name}"][-1] - expected)) / max(1.0, np.max(np.abs(expected)))
            assert difference <= 1e-10, name
        for f in (a, b):
            energy = f["energy"][()]
            assert np.max(np.abs(energy - energy[0])) <= 1e-13 * np.max(np.abs(energy))
