"""The SUNDIALS CVODE baselines on the same GENERIC right-hand side: they run the paper scene with
the common output layout, agree with PETSc's adaptive Dormand-Prince at tight tolerance, their
error falls with the tolerance, they vary their order, and they refuse constraints."""
import numpy as np
import pytest

from conftest import read_run, run_eme

CVODE_SCHEMES = ["cvode_bdf", "cvode_adams"]


def final_state(tmp_path, name, scheme, tolerance, **extra):
    result, path = run_eme(tmp_path, name, {"integrator": {"scheme": scheme, "dt": 0.6, "t_end": 2.4,
                                                           "tolerance": tolerance, **extra}})
    assert result.returncode == 0, result.stderr
    run = read_run(path)
    return np.concatenate([run["state"][-1, :13], run["temperature"][-1] / 300.0]), run


@pytest.mark.parametrize("scheme", CVODE_SCHEMES)
def test_cvode_runs_the_paper_scene(tmp_path, eme_run_binary, scheme):
    result, path = run_eme(tmp_path, scheme, {"integrator": {"scheme": scheme, "t_end": 3.0}})
    assert result.returncode == 0, result.stderr
    run = read_run(path)
    assert run["attrs"]["scheme"] == scheme and run["attrs"]["scheme_family"] == "sundials_cvode"
    assert run["attrs"]["status"] == "complete" and run["state"].shape == (21, 15)
    np.testing.assert_allclose(run["time"], 0.15 * np.arange(21), rtol=1e-14)
    assert np.all(run["temperature"] > 0)
    assert run["snes_solves"].sum() > 20    # CVODE's internal steps


@pytest.mark.parametrize("scheme,highest", [("cvode_bdf", 5), ("cvode_adams", 12)])
def test_cvode_raises_its_order(tmp_path, eme_run_binary, scheme, highest):
    # Output every 2 ms shows the order of the last internal step: it varies, within the method's
    # limit (5 for BDF, 12 for Adams), and Adams goes beyond what BDF can.
    result, path = run_eme(tmp_path, scheme, {"integrator": {"scheme": scheme, "dt": 0.002, "t_end": 0.2}})
    assert result.returncode == 0, result.stderr
    orders = read_run(path)["method_order"].astype(int)
    assert len(set(orders)) >= 2 and 4 <= orders.max() <= highest, orders
    if scheme == "cvode_adams":
        assert orders.max() > 5, orders


@pytest.mark.parametrize("scheme", CVODE_SCHEMES)
def test_cvode_agrees_with_ts_rk5dp_and_converges_with_tolerance(tmp_path, eme_run_binary, scheme):
    reference, _ = final_state(tmp_path, "reference", "ts_rk5dp", 1e-13)
    errors = [np.abs(final_state(tmp_path, f"tol{k}", scheme, 10.0 ** -k)[0] - reference).max() for k in (6, 9, 12)]
    # Measured: about 1e-4, 1e-6 and 2e-9 (BDF), 5e-5, 3e-7 and 4e-10 (Adams); the reference's own
    # error is below 1e-11 (test_baselines).
    assert errors[2] < 1e-8, errors
    assert errors[0] > 30 * errors[1] > 30 * 30 * errors[2], errors


def test_cvode_refuses_constraints(tmp_path, eme_run_binary):
    result, path = run_eme(tmp_path, "bad", {"constraints": {"fix_temperature": True},
                                             "integrator": {"scheme": "cvode_bdf"}})
    assert result.returncode == 2 and not path.exists()
    assert "scheme = 'cvode_bdf' integrates the unconstrained model only" in result.stderr
