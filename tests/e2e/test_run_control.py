"""Running eme_run as a user does: PETSc options reach the solver, a run that cannot
continue stops cleanly and keeps its steps in a valid file marked incomplete, a killed run
leaves a readable file, and memory does not grow with the number of steps."""
import re
import resource
import signal
import subprocess
import time

import h5py
import numpy as np
import pytest

from conftest import BIN, namelist_text, read_run, run_eme

POINT_DATASETS = ["time", "state", "temperature", "energy", "entropy", "lyapunov", "angular_momentum", "boundary_heat"]
STEP_DATASETS = ["newton_iterations", "scheme_temperature", "solver_strategy", "snes_solves", "rejected_roots"]


def assert_consistent(run, steps):
    """Every per-point dataset has steps+1 rows and every per-step dataset steps rows."""
    for name in POINT_DATASETS:
        assert run[name].shape[0] == steps + 1, name
    for name in STEP_DATASETS:
        assert run[name].shape[0] == steps, name
    assert run["attrs"]["steps_completed"] == steps


def test_run_that_cannot_continue_keeps_its_steps(tmp_path, eme_run_binary):
    # The midpoint rule with tau = u at dt = 2 s, halving switched off: on some step no strategy
    # finds a root with positive temperatures. (Whether one exists is the solver's verdict; halves
    # of the step find one, test_solver_robustness.py.)
    result, path = run_eme(tmp_path, "fails", {"integrator": {
        "scheme": "midpoint", "thermo_variable": "internal_energy", "dt": 2.0, "t_end": 60.0}},
        "-eme_max_halvings", "0")
    assert result.returncode == 3
    run = read_run(path)
    status = run["attrs"]["status"]
    failed = int(re.match(r"incomplete: step (\d+) \(t = ", status).group(1))
    assert status.startswith(f"incomplete: step {failed} (t = {2.0 * failed:.4f} s)") and 1 < failed < 30
    assert "no root" in status and status in result.stderr
    assert_consistent(run, failed - 1)
    assert np.all(run["temperature"] > 0)
    np.testing.assert_allclose(run["time"], 2.0 * np.arange(float(failed)))


def test_petsc_options_reach_the_solver(tmp_path, eme_run_binary):
    scene = {"integrator": {"t_end": 0.45}}
    result, _ = run_eme(tmp_path, "reason", scene, "-snes_converged_reason")
    assert result.returncode == 0
    assert result.stdout.count("Nonlinear solve converged due to") >= 3
    # With one Newton iteration allowed, no strategy can solve the first step.
    result, path = run_eme(tmp_path, "max_it", scene, "-snes_max_it", "1")
    assert result.returncode == 3
    run = read_run(path)
    assert run["attrs"]["status"].startswith("incomplete: step 1 ")
    assert_consistent(run, 0)


@pytest.mark.parametrize("scheme,variable,gradient", [
    ("eme", "entropy", "gonzalez"), ("eme", "temperature", "partitioned"),
    ("eme", "internal_energy", "gonzalez"), ("midpoint", "temperature", "gonzalez")])
def test_snes_test_jacobian_is_quiet(tmp_path, eme_run_binary, scheme, variable, gradient):
    result, _ = run_eme(tmp_path, "jacobian", {"integrator": {
        "scheme": scheme, "thermo_variable": variable, "discrete_gradient": gradient, "t_end": 0.6}},
        "-snes_test_jacobian")
    ratios = [float(x) for x in re.findall(r"\|\|J - Jfd\|\|_F/\|\|J\|\|_F = ([0-9.eE+-]+)", result.stdout)]
    assert len(ratios) >= 4
    # PETSc differences one-sidedly; its truncation error alone is ~1e-7 here.
    assert max(ratios) < 1e-5, ratios


def test_killed_run_leaves_a_readable_file(tmp_path, eme_run_binary):
    output = tmp_path / "killed.h5"
    namelist = tmp_path / "killed.nml"
    namelist.write_text(namelist_text({"integrator": {"dt": 0.05, "t_end": 1.0e6},
                                       "output": {"file": str(output)}}))
    process = subprocess.Popen([str(BIN / "eme_run"), str(namelist)])
    # Start-up time varies by machine: wait for the file, then for well over 256 steps (the
    # run takes under 0.1 ms per step here), then kill mid-run.
    deadline = time.time() + 120
    while not output.exists() and time.time() < deadline and process.poll() is None:
        time.sleep(0.05)
    time.sleep(2.0)
    process.send_signal(signal.SIGKILL)
    process.wait()
    with h5py.File(output, "r") as f:
        assert f.attrs["status"] == "incomplete: running"
        rows = f["time"].shape[0]
        assert rows >= 256
        for name in POINT_DATASETS:
            assert f[name].shape[0] == rows, name
        np.testing.assert_allclose(f["time"][:], 0.05 * np.arange(rows))
        energy = f["energy"][:]
        assert np.max(np.abs(energy - energy[0])) <= 1e-8 * abs(energy[0])


def peak_memory_kib(tmp_path, name, t_end):
    before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    result, _ = run_eme(tmp_path, name, {"integrator": {"scheme": "midpoint", "thermo_variable": "entropy",
                                                         "dt": 0.01, "t_end": t_end}})
    assert result.returncode == 0, result.stderr
    return max(before, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)


def test_memory_does_not_grow_with_steps(tmp_path, eme_run_binary):
    short = peak_memory_kib(tmp_path, "short", 5.0)      # 500 steps
    long = peak_memory_kib(tmp_path, "long", 300.0)      # 30000 steps: 30000 rows x 24 values = 5.8 MB
    assert long - short < 2048, f"peak RSS grew from {short} KiB to {long} KiB"
