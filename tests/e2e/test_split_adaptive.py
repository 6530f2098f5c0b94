"""EME's adaptive steps and the halving of fixed steps on the split path
(src/integrator/distributed_step_control.f90 over the chain's DMDA; docs/integrators.md, Adaptive
steps and "On the split path"):
- an adaptive split run on two ranks takes the dense path's adaptive run: the same accepted and
  rejected steps, times and E, S to rounding, landing on t_end exactly;
- one rank and two take the same adaptive steps (the estimate's norm is a sum over the ranks);
- every accepted step keeps E to round-off and each branch's and link's production >= 0, rows
  at every accepted step and snapshots every K-th and at the end;
- a fixed step too large for Newton is taken in halves, landing on t + dt: its end state is that
  of two steps of dt/2, bit for bit, and the counts (substeps, halved_steps) say so;
- an adaptive split run stopped by its step budget and continued with -eme_continue ends with the
  uninterrupted run's file, bit for bit (the controller's state is in the resume record);
- with &output interval the adaptive steps land on every output time, as the dense path's do: the
  same steps, rows and snapshots at the output times, states as the dense rows; an interval with
  a scheme whose steps land on n dt on this path, or with snapshot_every, is refused (exit 2,
  nothing written)."""
import h5py
import numpy as np
import pytest

from conftest import run_eme
from test_spring_chain_sparse import chain_groups, rod_groups
from test_split_runs import assert_continued_equals, run_split, snapshot_rows, write_input


def adaptive_chain():
    """The small dissipative chain (12 unlike springs, 1D, fixed-fixed, a temperature gradient) at
    tolerance 1e-4 from dt = 5 ms to 0.2 s: 59 accepted steps and one rejection; Newton at its
    rounding floor on both paths."""
    groups = chain_groups(links=12, dimension=1, ends="fixed-fixed", steps=40, dt=0.005, newton_tol=1.0e-30)
    groups["integrator"]["tolerance"] = 1.0e-4
    groups["output"] = {"snapshot_every": 10}
    return groups


def adaptive_rod():
    """The 300-spring rod (1198 unknowns: split on one rank too) at tolerance 1e-3 to 2 ms."""
    groups = rod_groups(300, 20)
    groups["integrator"].update(tolerance=1.0e-3, newton_tol=1.0e-30)
    groups["output"] = {"snapshot_every": 7}
    return groups


def assert_every_step_kept(f, t_end, every):
    """Complete, landing on t_end exactly, every accepted step in a row and checked: E to round-off
    (the energy balance within its rounding bound of 32 ulps, E's steps 1e-13 of E), S rising, the
    productions >= 0; snapshots every `every`-th accepted step and at the end."""
    assert f.attrs["status"] == "complete" and f.attrs["failure_kind"] == "none"
    time = f["time"][()]
    assert time[-1] == t_end                                    # exactly, not to rounding
    assert np.all(np.diff(time) > 0.0)
    steps = f.attrs["steps_completed"]
    assert time.size == steps + 1 and f["step_size"].shape == (steps,)
    assert np.allclose(np.cumsum(f["step_size"][()]), time[1:], rtol=1e-12, atol=0.0)
    balance = f["balance"][()]
    assert np.all(balance[np.isfinite(balance)] <= 32.0)
    energy = f["energy"][()]
    assert np.max(np.abs(np.diff(energy))) <= 1e-13 * np.max(np.abs(energy))
    assert np.all(np.diff(f["entropy"][()]) >= 0.0)
    assert np.all(f["min_viscous_production"][()] >= 0.0) and np.all(f["min_link_production"][()] >= 0.0)
    # The error estimate of every accepted step is within the tolerance per unit step.
    tolerance = f.attrs["tolerance"]
    assert np.all(f["error_estimate"][()] <= tolerance * f["step_size"][()] + 64 * np.finfo(float).eps)
    expected = list(time[::every])
    if expected[-1] != time[-1]:
        expected.append(time[-1])
    assert np.array_equal(f["snapshots/time"][()], expected)


def test_an_adaptive_split_run_is_the_dense_adaptive_run(tmp_path):
    """The dense path (one process, dense LU) and the split path (two ranks, SNES on the DMDA)
    solve the same step equations to Newton's rounding floor and measure the same estimate: the
    same steps are accepted and rejected. The roots differ at their rounding (16 eps |z|, |z| ~
    300 K), which the estimate, a difference quotient (z_new - z_old)/h of a 1e-7 defect, carries
    at ~1e-9 relative (measured 1.7e-9; asserted 1e-7); the controller's h ~ err^-0.35 passes it
    on damped: step sizes and times agree to 1e-8 relative (measured 5.7e-10 and 5e-11). E and S,
    sums of the springs' values, agree to 1e-12 of their largest values (measured 9e-15, 4e-14),
    V = E - theta_r S, a difference of the two, to 1e-11 (measured 4e-13)."""
    groups = adaptive_chain()
    result, dense_file = run_eme(tmp_path, "dense", groups)
    assert result.returncode == 0, result.stderr
    result, split_file = run_split(tmp_path, "split", groups)
    assert result.returncode == 0, result.stderr
    with h5py.File(dense_file, "r") as dense, h5py.File(split_file, "r") as split:
        assert_every_step_kept(split, 0.2, 10)
        assert dense["time"][-1] == 0.2
        assert split.attrs["steps_completed"] == dense.attrs["steps_completed"] == dense.attrs["steps_planned"]
        for name in ("rejected_steps", "rejected_error", "rejected_no_root", "rejected_domain", "substeps"):
            assert np.array_equal(split[name][()], dense[name][()]), name
        assert np.sum(split["rejected_steps"][()]) >= 1                       # the controller did reject
        assert split.attrs["run_figures"][6] == dense.attrs["run_figures"][6]     # rejected_steps in total
        for name in ("time", "step_size"):
            a, b = dense[name][()], split[name][()]
            assert np.max(np.abs(a - b)) <= 1e-8 * np.max(np.abs(a)), name
        a, b = dense["error_estimate"][()], split["error_estimate"][()]
        assert np.max(np.abs(a - b) / a) <= 1e-7
        for name, tolerance in (("energy", 1e-12), ("entropy", 1e-12), ("lyapunov", 1e-11)):
            a, b = dense[name][()], split[name][()]
            assert np.max(np.abs(a - b)) <= tolerance * np.max(np.abs(a)), name


def test_one_rank_and_two_give_the_same_adaptive_split_run(tmp_path):
    """The 300-spring rod at tolerance 1e-3 on one rank and on two: the same steps (79 accepted, 3
    rejected), times and steps to 1e-6 relative, E and S to 1e-12. The estimate's norm is each
    rank's sum of squares added by MPI_Allreduce, the same up to the rounding of that sum; the
    roots differ at Newton's floor, on two ranks reached through GMRES (1e-12 relative) instead of
    one LU, and the estimate, here 3e-8 a difference quotient at a tolerance per step of 3e-8,
    carries that at ~1e-7 relative: the step sizes differ by 3.2e-8 relative (measured)."""
    groups = adaptive_rod()
    one, one_file = run_split(tmp_path, "one", groups, 1)
    assert one.returncode == 0, one.stderr
    two, two_file = run_split(tmp_path, "two", groups, 2)
    assert two.returncode == 0, two.stderr
    with h5py.File(one_file, "r") as a, h5py.File(two_file, "r") as b:
        assert_every_step_kept(a, 2e-3, 7)
        assert_every_step_kept(b, 2e-3, 7)
        assert a.attrs["steps_completed"] == b.attrs["steps_completed"]
        assert np.array_equal(a["rejected_steps"][()], b["rejected_steps"][()])
        assert np.sum(a["rejected_steps"][()]) >= 1
        for name in ("time", "step_size"):
            assert np.max(np.abs(a[name][()] - b[name][()])) <= 1e-6 * np.max(np.abs(a[name][()])), name
        for name in ("energy", "entropy"):
            assert np.max(np.abs(a[name][()] - b[name][()])) <= 1e-12 * np.max(np.abs(a[name][()])), name


def colliding_chain(dt, steps):
    """The small chain with mass 6 thrown at 150 kg m/s toward mass 7: at dt = 0.1 s Newton from
    the old state finds no root of EME's first step, at 0.05 s it does (measured)."""
    groups = chain_groups(links=12, dimension=1, ends="fixed-fixed", steps=steps, dt=dt, newton_tol=1.0e-30)
    groups["initial"]["p"] = [0.0] * 5 + [150.0] + [0.0] * 6
    groups["output"] = {"snapshot_every": 1}
    return groups


def test_a_fixed_split_step_without_a_root_is_taken_in_halves(tmp_path):
    """One step of 0.1 s whose Newton fails is replaced by two of 0.05 s: the run lands on 0.1 s,
    records 2 substeps and one halved step, keeps its balance over the step, and ends in the state
    of a run of two 0.05 s steps, bit for bit (the same two solves from the same states)."""
    halved, halved_file = run_split(tmp_path, "halved", colliding_chain(0.1, 1))
    assert halved.returncode == 0, halved.stderr
    halves, halves_file = run_split(tmp_path, "halves", colliding_chain(0.05, 2))
    assert halves.returncode == 0, halves.stderr
    with h5py.File(halved_file, "r") as a, h5py.File(halves_file, "r") as b:
        assert a.attrs["status"] == "complete" and np.array_equal(a["time"][()], [0.0, 0.1])
        assert np.array_equal(a["substeps"][()], [2.0])
        assert a.attrs["run_figures"][5] == 1                       # halved_steps
        assert np.array_equal(b["substeps"][()], [1.0, 1.0]) and b.attrs["run_figures"][5] == 0
        # the failed solve's iterations count too (here none: its first update leaves the domain)
        assert a["newton_iterations"][0] >= b["newton_iterations"][0] + b["newton_iterations"][1]
        assert a["snes_solves"][0] == 3 and a["converged_reason"][0] > 0
        balance = a["balance"][()]
        assert np.all(balance[np.isfinite(balance)] <= 32.0)
        for name in ("q", "p", "gamma", "theta"):
            assert np.array_equal(a[f"snapshots/{name}"][-1], b[f"snapshots/{name}"][-1]), name
        assert a["energy"][-1] == b["energy"][-1] and a["entropy"][-1] == b["entropy"][-1]


def test_a_continued_adaptive_split_run_is_the_uninterrupted_run(tmp_path):
    """The adaptive rod on two ranks stopped by its step budget (30 accepted steps, a snapshot at
    the stop) and continued with -eme_continue (max_steps raised) ends with the uninterrupted
    run's file, rows and snapshots bit for bit: the controller's next step and error history
    are restored from the resume record, as on the dense path."""
    groups = adaptive_rod()
    stopped = {key: dict(fields) for key, fields in groups.items()}
    stopped["integrator"]["max_steps"] = 30
    result, continued_file = run_split(tmp_path, "continued", stopped)
    assert result.returncode == 3, result.stderr
    part = tmp_path / "continued.h5.part"
    with h5py.File(part if part.exists() else continued_file, "r") as f:
        assert f.attrs["failure_kind"] == "step_budget"
        assert f.attrs["status"].startswith("incomplete: the step budget is spent: 30 steps reached t = ")
        stop_time = f["time"][-1]
        assert f["snapshots/time"][-1] == stop_time
    full, full_file = run_split(tmp_path, "full", groups)
    assert full.returncode == 0, full.stderr
    resumed, _ = run_split(tmp_path, "continued", groups, 2, "-eme_continue")
    assert resumed.returncode == 0, resumed.stderr
    assert_continued_equals(full_file, continued_file, exact=True, stop_times=[stop_time])
    with h5py.File(full_file, "r") as full, h5py.File(continued_file, "r") as continued:
        assert np.array_equal(full["step_size"][()], continued["step_size"][()])
        assert np.array_equal(full.attrs["run_figures"], continued.attrs["run_figures"], equal_nan=True)


def test_an_adaptive_split_run_lands_on_the_output_times_as_the_dense_one(tmp_path):
    """The small chain at tolerance 1e-4 with &output interval = 0.05 s on two ranks against the
    dense path: the steps are shortened to land on 0.05, 0.1, 0.15 and 0.2 s (the rows are those
    times exactly, computed as k * 0.05 on both paths), the split run holds a snapshot at each of
    them, and its states there are the dense path's rows to 1e-8 of max(1, |z|): the step sizes
    agree to 1e-8 relative as in the run without an interval (the roots differ at Newton's
    floor); every accepted step is checked and kept, as without an interval."""
    groups = adaptive_chain()
    groups["output"] = {"interval": 0.05}
    result, dense_file = run_eme(tmp_path, "dense", groups)
    assert result.returncode == 0, result.stderr
    result, split_file = run_split(tmp_path, "split", groups)
    assert result.returncode == 0, result.stderr
    output_times = [k * 0.05 for k in range(1, 4)] + [0.2]
    with h5py.File(dense_file, "r") as dense, h5py.File(split_file, "r") as split:
        assert split.attrs["status"] == "complete" and split.attrs["failure_kind"] == "none"
        assert np.array_equal(dense["time"][()], [0.0] + output_times)
        assert np.array_equal(split["time"][()], dense["time"][()])
        assert np.array_equal(split["snapshots/time"][()], dense["time"][()])
        # The accepted steps end on each output time (the cumulated step sizes pass through them).
        ends = np.cumsum(split["step_size"][()])
        for t in output_times:
            assert np.min(np.abs(ends - t)) <= 1e-12, t
        assert split.attrs["steps_completed"] == dense.attrs["steps_completed"]
        a, b = dense["step_size"][()], split["step_size"][()]
        assert np.max(np.abs(a - b)) <= 1e-8 * np.max(a)
        for name in ("energy", "entropy"):
            a, b = dense[name][()], split[name][()]
            assert np.max(np.abs(a - b)) <= 1e-12 * np.max(np.abs(a)), name
        for row in range(len(output_times) + 1):
            q, p, gamma, theta = snapshot_rows(dense["state"][row], 12, 1, True)
            for name, expected in (("q", q), ("p", p), ("gamma", gamma), ("theta", theta)):
                got = split[f"snapshots/{name}"][row]
                assert np.max(np.abs(got - expected)) <= 1e-8 * max(1.0, np.max(np.abs(expected))), (name, row)
        balance = split["balance"][()]
        assert np.all(balance[np.isfinite(balance)] <= 32.0)
        assert np.all(np.diff(split["entropy"][()]) >= 0.0)
        assert np.all(split["min_viscous_production"][()] >= 0.0) and np.all(split["min_link_production"][()] >= 0.0)


def test_a_continued_split_run_with_an_output_interval_is_the_uninterrupted_run(tmp_path):
    """The adaptive rod on two ranks with &output interval = 0.5 ms, stopped by its step budget
    between two output times: its rows go to the stop, its snapshots are those of the output
    times (its resume record stands at the last of them, as the dense path's); continued, it
    takes the steps from there again and ends with the uninterrupted run's file, bit for bit (the
    output times already passed follow from the time it starts at)."""
    groups = adaptive_rod()
    groups["output"] = {"interval": 5.0e-4}
    stopped = {key: dict(fields) for key, fields in groups.items()}
    stopped["integrator"]["max_steps"] = 30
    result, continued_file = run_split(tmp_path, "continued", stopped)
    assert result.returncode == 3, result.stderr
    part = tmp_path / "continued.h5.part"
    with h5py.File(part if part.exists() else continued_file, "r") as f:
        assert f.attrs["failure_kind"] == "step_budget"
        stopped_at = f["snapshots/time"][()]
        assert np.array_equal(stopped_at, [0.0, 5.0e-4])
        assert f["time"][-1] > stopped_at[-1] and f.attrs["resume_numbers"][0] < 30
    full, full_file = run_split(tmp_path, "full", groups)
    assert full.returncode == 0, full.stderr
    with h5py.File(full_file, "r") as f:
        assert np.array_equal(f["time"][()], [0.0, 5.0e-4, 1.0e-3, 3 * 5.0e-4, 2.0e-3])
        assert np.array_equal(f["snapshots/time"][()], f["time"][()])
        assert f.attrs["steps_completed"] > 30 and stopped_at[-1] < f["time"][-1]
    resumed, _ = run_split(tmp_path, "continued", groups, 2, "-eme_continue")
    assert resumed.returncode == 0, resumed.stderr
    assert_continued_equals(full_file, continued_file, exact=True)
    with h5py.File(full_file, "r") as full, h5py.File(continued_file, "r") as continued:
        assert np.array_equal(full["time"][()], continued["time"][()])
        assert np.array_equal(full["step_size"][()], continued["step_size"][()])


@pytest.mark.parametrize("change, field", [({}, "interval"), ({"output": {"snapshot_every": 2}}, "snapshot_every")])
def test_an_output_interval_the_split_path_cannot_follow_is_refused(tmp_path, change, field):
    """EME without a tolerance steps on n dt, so an interval is refused for it (as for the TS
    baselines); with an interval the snapshots are at the output times, so snapshot_every as well
    is refused. Exit 2, the file and field named, nothing written."""
    groups = adaptive_chain()
    groups["output"] = {"interval": 0.05}
    for group, fields in change.items():
        groups[group].update(fields)
    if not change:
        del groups["integrator"]["tolerance"]
    result, _ = run_split(tmp_path, "refused", groups)
    assert result.returncode == 2, result.stderr
    assert "&output: interval" in result.stderr and "refused.nml" in result.stderr and field in result.stderr
    assert not list(tmp_path.glob("refused.h5*"))
