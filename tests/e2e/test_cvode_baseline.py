"""build/bin/cvode_baseline, make bench's whole-run baseline (a C program on SUNDIALS CVODE alone),
integrates the same model as eme_run: its final state at t = 20 s agrees with eme_run's cvode_bdf
at the same tolerance to within the global error of such a run, it takes as many internal steps,
and its analytic Jacobian matches central differences of its own right-hand side."""
import subprocess

import numpy as np
import pytest

from conftest import BIN, read_run, run_eme

TEMPERATURE_SCALE = 300.0   # K: temperatures enter the error relative to theta_ref, as in the studies


def baseline(*arguments):
    """Runs cvode_baseline; its printed state and counts."""
    binary = BIN / "cvode_baseline"
    assert binary.exists(), f"{binary} is missing: run `make` first"
    result = subprocess.run([str(binary), *arguments], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    fields = {}
    for line in result.stdout.splitlines():
        if line.startswith("state="):
            fields["state"] = np.array([float(x) for x in line[len("state="):].split()])
        elif "=" in line and not line.startswith("cvode_baseline:"):
            fields.update((key, float(value)) for key, value in (word.split("=") for word in line.split()))
    return fields


def eme_run_cvode_bdf(tmp_path, tolerance):
    """eme_run's cvode_bdf on the paper scene to t = 20 s (output every 0.5 s), temperature
    variable: the final state and its internal steps."""
    result, path = run_eme(tmp_path, f"cvode_bdf_{tolerance:g}", {"integrator": {
        "scheme": "cvode_bdf", "thermo_variable": "temperature", "dt": 0.5, "t_end": 20.0, "tolerance": tolerance}})
    assert result.returncode == 0, result.stderr
    run = read_run(path)
    assert run["time"][-1] == pytest.approx(20.0, abs=1e-12)
    return np.concatenate([run["state"][-1, :13], run["temperature"][-1]]), int(run["snes_solves"].sum())


def distance(a, b):
    """max |q, p, gamma - ...| and |theta - ...|/theta_ref, the studies' error measure."""
    return max(np.abs(a[:13] - b[:13]).max(), np.abs(a[13:] - b[13:]).max() / TEMPERATURE_SCALE)


def test_cvode_baseline_is_eme_runs_model(tmp_path, eme_run_binary):
    ours = baseline()   # as make bench runs it: rtol = atol = 1e-10, to t = 20 s
    assert ours["t_final"] == 20.0 and ours["state"].shape == (15,)
    theirs, their_steps = eme_run_cvode_bdf(tmp_path, 1e-10)
    tighter, _ = eme_run_cvode_bdf(tmp_path, 1e-12)
    # Both are CVODE BDF at 1e-10 from the same state on the same field; they differ only in their
    # step sequences (eme_run stops at every output time, and its Jacobian rounds otherwise), so
    # they may differ by up to the sum of both runs' global errors, each estimated by the run's
    # change under a 100 times tighter tolerance. Measured 2026-11-29 with the generated rungs:
    # 8.7e-5 apart against errors of 3.5e-5 (eme_run) and 5.8e-5 (cvode_baseline); before them
    # 7.8e-6 against 5.4e-5: at t = 20 s the pendulum amplifies a rounding's difference in the
    # step sequence to the tolerance's global error, so which of the two is the larger is chance.
    # A parameter of the model doubled or of the wrong sign moves the state at t = 20 s by 1e-2 or
    # more.
    own_error = distance(theirs, tighter)
    assert 1e-7 < own_error < 1e-3, own_error
    baseline_error = distance(ours["state"], baseline("--tolerance", "1e-12")["state"])
    assert 1e-7 < baseline_error < 1e-3, baseline_error
    apart = distance(ours["state"], theirs)
    assert apart < 2.0 * (own_error + baseline_error), (apart, own_error, baseline_error)
    # The same method at the same tolerance takes as many internal steps (11510 and 11416 here).
    assert abs(ours["steps"] - their_steps) < 0.05 * their_steps, (ours["steps"], their_steps)
    assert ours["jacobian_evaluations"] > 0 and ours["nonlinear_failures"] == 0


def test_cvode_baseline_jacobian_matches_central_differences():
    # At the final state (every component nonzero), relative to each row's largest entry;
    # central differences err by about 1e-9 here (measured 9e-10), a wrong term by 1e-3 or more.
    fields = baseline("--tolerance", "1e-6", "--check-jacobian")
    assert fields["jacobian_deviation"] < 1e-7, fields["jacobian_deviation"]


def test_cvode_baseline_difference_quotients_reach_the_same_state():
    # CVODE's own difference-quotient Jacobian changes the Newton iterations, not the solution:
    # the two runs at 1e-10 end 1.8e-5 apart (measured), within the 6e-5 global error of either
    # (test above), with the same steps to within a few.
    analytic, quotients = baseline(), baseline("--difference-quotients")
    assert distance(analytic["state"], quotients["state"]) < 1e-4
    assert abs(analytic["steps"] - quotients["steps"]) < 0.01 * analytic["steps"]
    assert quotients["rhs_evaluations"] > analytic["rhs_evaluations"]   # 15 more per Jacobian


def test_cvode_baseline_refuses_bad_arguments():
    binary = BIN / "cvode_baseline"
    for arguments in (["--tolerance", "-1"], ["--t-end"], ["--frobnicate"]):
        result = subprocess.run([str(binary), *arguments], capture_output=True, text=True, timeout=60)
        assert result.returncode == 2 and "usage: cvode_baseline" in result.stderr, (arguments, result.stderr)


def test_arkode_dp5_integrates_the_paper_scene_at_fifth_order(tmp_path, eme_run_binary):
    # cvode_baseline --arkode-dp5, make bench's outside program for relaxed_dp853's work-precision
    # line (postprocess/bench_arkode.py): at t = 5 s it agrees with eme_run's relaxed_dp853 (a
    # code written apart: other field, other method) to within both runs' errors (each about 1e-9
    # at 1e-11, measured 2026-11-29: 1.3e-10 and 6.5e-10 against their own 1e-13 runs) ...
    ours = baseline("--arkode-dp5", "--tolerance", "1e-11", "--t-end", "5")
    assert ours["t_final"] == 5.0
    result, path = run_eme(tmp_path, "relaxed_dp853", {"integrator": {
        "scheme": "relaxed_dp853", "thermo_variable": "temperature", "dt": 0.15, "t_end": 5.0, "tolerance": 1e-11}})
    assert result.returncode == 0, result.stderr
    run = read_run(path)
    assert distance(ours["state"], np.concatenate([run["state"][-1, :13], run["temperature"][-1]])) < 1e-8
    # ... and its steps grow like tol^(-1/5), as a fifth-order error control's do: 10 times for
    # 1e5 times tighter (a second-order table would take 10^2.5 = 316 times as many).
    looser = baseline("--arkode-dp5", "--tolerance", "1e-6", "--t-end", "5")
    assert 6 < ours["steps"] / looser["steps"] < 16, (ours["steps"], looser["steps"])
