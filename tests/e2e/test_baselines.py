"""The PETSc TS baselines on the same GENERIC right-hand side: they run the paper scene with the
common output layout, PETSc's theta = 1/2 method reproduces our midpoint rule, each converges
at its order, their Jacobian is right, and they refuse constraints."""
import re

import numpy as np
import pytest

from conftest import read_run, run_eme

TS_SCHEMES = ["ts_midpoint", "ts_bdf2", "ts_rk4", "ts_rk5dp"]


@pytest.mark.parametrize("scheme", TS_SCHEMES)
def test_baseline_runs_the_paper_scene(tmp_path, eme_run_binary, scheme):
    result, path = run_eme(tmp_path, scheme, {"integrator": {"scheme": scheme, "t_end": 3.0}})
    assert result.returncode == 0, result.stderr
    run = read_run(path)
    assert run["attrs"]["scheme"] == scheme and run["attrs"]["discrete_gradient"] == "none"
    assert run["attrs"]["scheme_family"] == "petsc_ts"
    assert run["attrs"]["status"] == "complete" and run["state"].shape == (21, 15)
    np.testing.assert_allclose(run["time"], 0.15 * np.arange(21), rtol=1e-14)
    if scheme != "ts_rk5dp":
        assert np.all(run["snes_solves"] == 1)        # one TS step per output step
    assert np.all(run["temperature"] > 0)


@pytest.mark.parametrize("variable", ["entropy", "temperature", "internal_energy"])
def test_ts_theta_half_is_our_midpoint_rule(tmp_path, eme_run_binary, variable):
    runs = []
    for scheme in ("midpoint", "ts_midpoint"):
        result, path = run_eme(tmp_path, scheme, {"integrator": {"scheme": scheme, "thermo_variable": variable,
                                                                  "t_end": 3.0}})
        assert result.returncode == 0, result.stderr
        runs.append(read_run(path))
    # Both solve z' = z + dt f(z_mid) to the Newton tolerance 1e-8.
    np.testing.assert_allclose(runs[1]["state"], runs[0]["state"], rtol=0, atol=1e-6)


def final_state(tmp_path, name, scheme, dt, **extra):
    result, path = run_eme(tmp_path, name, {"integrator": {"scheme": scheme, "dt": dt, "t_end": 0.6, **extra}})
    assert result.returncode == 0, result.stderr
    run = read_run(path)
    return np.concatenate([run["state"][-1, :13], run["temperature"][-1] / 300.0])


@pytest.mark.parametrize("scheme,order", [("ts_midpoint", 2), ("ts_bdf2", 2), ("ts_rk4", 4)])
def test_baseline_order(tmp_path, eme_run_binary, scheme, order):
    reference = final_state(tmp_path, "reference", "ts_rk5dp", 0.02, ts_tolerance=1e-13)
    steps = [0.02, 0.01, 0.005]
    errors = [np.abs(final_state(tmp_path, f"dt{i}", scheme, dt) - reference).max() for i, dt in enumerate(steps)]
    observed = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(np.abs(observed - order) < 0.2), f"errors {errors}, orders {observed}"


def test_adaptive_reference_is_consistent(tmp_path, eme_run_binary):
    tight = final_state(tmp_path, "tight", "ts_rk5dp", 0.02, ts_tolerance=1e-13)
    looser = final_state(tmp_path, "looser", "ts_rk5dp", 0.02, ts_tolerance=1e-10)
    assert np.abs(looser - tight).max() < 1e-8
    # Cross-check by an independent method: EME_theta's error against the reference falls at
    # second order down to dt/64, which it could not if the reference were off by that much.
    errors = [np.abs(final_state(tmp_path, f"eme{k}", "eme", 0.02 / k) - tight).max() for k in (32, 64)]
    assert 1.85 < np.log2(errors[0] / errors[1]) < 2.15, errors


@pytest.mark.parametrize("scheme", ["ts_midpoint", "ts_bdf2"])
def test_baseline_jacobian_is_quiet(tmp_path, eme_run_binary, scheme):
    result, _ = run_eme(tmp_path, "jacobian", {"integrator": {"scheme": scheme, "t_end": 0.45}},
                        "-snes_test_jacobian")
    ratios = [float(x) for x in re.findall(r"\|\|J - Jfd\|\|_F/\|\|J\|\|_F = ([0-9.eE+-]+)", result.stdout)]
    assert len(ratios) >= 3 and max(ratios) < 1e-5, ratios


def test_baselines_refuse_constraints(tmp_path, eme_run_binary):
    result, path = run_eme(tmp_path, "bad", {"constraints": {"fix_length": True},
                                             "integrator": {"scheme": "ts_rk4"}})
    assert result.returncode == 2 and not path.exists()
    assert "scheme = 'ts_rk4' integrates the unconstrained model only" in result.stderr


# The harder scene of the stability study: fast motion and a wide temperature gap, where large
# steps carry Runge-Kutta stages out of the model's domain (a non-positive temperature).
HARD_SCENE = {"initial": {"p2": [-5.0, -5.0, 0.0], "theta": [200.0, 350.0]}}


@pytest.mark.parametrize("variable", ["temperature", "internal_energy"])
def test_adaptive_method_steps_back_from_the_domain_boundary(tmp_path, eme_run_binary, variable):
    # Its stages leave the domain at dt = 1 s: the stage check rejects them and the method
    # retries with smaller steps, instead of PETSc failing on a NaN error estimate.
    result, path = run_eme(tmp_path, "rk5dp", {**HARD_SCENE, "integrator": {
        "scheme": "ts_rk5dp", "thermo_variable": variable, "dt": 1.0, "t_end": 4.0, "ts_tolerance": 1e-6}})
    assert result.returncode == 0, result.stderr
    run = read_run(path)
    assert run["attrs"]["status"] == "complete" and np.all(run["temperature"] > 0)
    assert run["rejected_roots"].sum() > 0


def test_fixed_step_method_stops_cleanly_when_a_stage_leaves_the_domain(tmp_path, eme_run_binary):
    result, path = run_eme(tmp_path, "rk4", {**HARD_SCENE, "integrator": {
        "scheme": "ts_rk4", "thermo_variable": "internal_energy", "dt": 1.0, "t_end": 4.0}})
    assert result.returncode == 3, result.stderr
    run = read_run(path)
    assert run["attrs"]["status"].startswith("incomplete: step 1 (t = 1.0000 s): PETSc TS: a stage left the model's domain")
    assert run["time"].tolist() == [0.0]
