"""The modified Newton (src/solver/modified_newton, -eme_modified_newton true by default) keeps the
LU factors while they contract and accepts a chord iterate only where the error it leaves is below
eps |z| h/(64 s). A chord iterate's error is systematic and adds up from step to step, so the
tests hold it where chord iterates are accepted most: a run of 40,000 steps, whose energy balance
and J_z must stay within the random walk of round-off, 32 sqrt(N) ulps (N steps; measured
2.9e-13 = 6 sqrt(N) ulps of |E_0|; an acceptance of eps |z| per step instead drifted to 7e-11).
With -eme_modified_newton false the iteration is the previous one, Newton for Newton."""
import numpy as np

from conftest import read_run, run_eme

EPS = np.finfo(float).eps
NO_CONDUCTION = {"model": {"conductivity": 0.0}, "initial": {"theta(2)": 300.0},
                 "integrator": {"scheme": "eme", "thermo_variable": "temperature", "dt": 5e-4}}


def test_energy_and_angular_momentum_stay_at_round_off_over_40000_steps(tmp_path, eme_run_binary):
    result, path = run_eme(tmp_path, "long", NO_CONDUCTION)
    assert result.returncode == 0, result.stderr
    run = read_run(path)
    steps = run["attrs"]["steps_completed"]
    assert steps == 40000
    bound = 32 * np.sqrt(steps) * EPS
    energy, jz = run["energy"], run["angular_momentum"][:, 2]
    assert np.max(np.abs(energy - energy[0])) <= bound * abs(energy[0])
    assert np.max(np.abs(jz - jz[0])) <= bound * abs(jz[0])


def test_switched_off_the_iteration_is_the_previous_one(tmp_path, eme_run_binary):
    # The paper scene with EME_theta took 549 Newton iterations before the modified Newton (4.10 a step).
    result, path = run_eme(tmp_path, "previous", {"integrator": {"thermo_variable": "temperature"}},
                           "-eme_modified_newton", "false")
    assert result.returncode == 0, result.stderr
    run = read_run(path)
    assert int(run["newton_iterations"].sum()) == 549
    assert run["attrs"]["solver_eme_modified_newton"] == "false"
