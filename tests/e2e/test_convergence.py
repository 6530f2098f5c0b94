"""Second-order convergence of EME and the midpoint rule on a short interval, measured
against a run of the same scheme with a 16 times smaller step than the finest one."""
import numpy as np
import pytest

from conftest import read_run, run_eme

T_END = 0.5
STEPS = [0.02, 0.01, 0.005]
REFERENCE_STEP = STEPS[-1] / 16
CASES = [(scheme, variable, gradient)
         for variable in ["entropy", "temperature", "internal_energy"]
         for scheme, gradient in [("eme", "gonzalez"), ("eme", "partitioned"), ("midpoint", "gonzalez")]]


def final_error(run, reference):
    """Largest error at t = T_END over positions [m], momenta [N s], gamma [m] and temperatures
    relative to theta_ref (the thermodynamic variable itself has different units per run)."""
    mechanical = np.abs(run["state"][-1, :13] - reference["state"][-1, :13]).max()
    thermal = np.abs(run["temperature"][-1] - reference["temperature"][-1]).max() / 300.0
    return max(mechanical, thermal)


@pytest.mark.parametrize("scheme,variable,gradient", CASES)
def test_second_order(tmp_path, eme_run_binary, scheme, variable, gradient):
    def run(dt, name):
        result, path = run_eme(tmp_path, name, {"integrator": {
            "scheme": scheme, "thermo_variable": variable, "discrete_gradient": gradient,
            "dt": dt, "t_end": T_END}})
        assert result.returncode == 0, result.stderr
        data = read_run(path)
        assert abs(data["time"][-1] - T_END) < 1e-12
        return data

    reference = run(REFERENCE_STEP, "reference")
    errors = [final_error(run(dt, f"dt{i}"), reference) for i, dt in enumerate(STEPS)]
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all((orders > 1.85) & (orders < 2.15)), f"errors {errors}, observed orders {orders}"
