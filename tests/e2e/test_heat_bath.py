"""The heat-bath oscillator generated from src/model/heat_bath/description.py (docs/formulation.md
section 11) against closed forms typed here from the physics, not from the code: without friction
the harmonic oscillator q0 cos(w t) + p0/(m w) sin(w t) at constant temperature; with the linear
drag alone the damped oscillator, its lost mechanical energy in the bath of constant heat capacity
c (theta = theta_0 + (E_mech(0) - E_mech(t))/c, S = c ln(theta/theta_ref)). Then every integrator
of the registry on the default scene (linear and cubic drag): E kept, S never falling, and the three
thermodynamic variables giving the same motion."""
import subprocess

import h5py
import numpy as np
import pytest

from conftest import BIN, run_eme

MASS, STIFFNESS, CAPACITY, THETA_REF = 1.0, 4.0, 2.0, 300.0
VARIABLES = ["entropy", "temperature", "internal_energy"]


def integrators():
    """The names and keeps_structure of `eme_run --integrators`."""
    listing = subprocess.run([str(BIN / "eme_run"), "--integrators"], capture_output=True, text=True, timeout=60)
    assert listing.returncode == 0, listing.stderr
    rows = [line.split("\t") for line in listing.stdout.splitlines()]
    column = rows[0].index("keeps_structure")
    return {row[0]: row[column] == "yes" for row in rows[1:]}


def damped(t, q0, p0, theta0, friction):
    """(q, p, theta, S) of m q'' = -k q - nu q' and the bath heated by the lost mechanical energy."""
    gamma = friction/(2*MASS)
    omega = np.sqrt(STIFFNESS/MASS - gamma**2)
    a, b = q0, (p0/MASS + gamma*q0)/omega
    decay = np.exp(-gamma*t)
    q = decay*(a*np.cos(omega*t) + b*np.sin(omega*t))
    v = decay*((b*omega - gamma*a)*np.cos(omega*t) - (gamma*b + a*omega)*np.sin(omega*t))
    p = MASS*v
    mechanical = p**2/(2*MASS) + STIFFNESS*q**2/2
    theta = theta0 + (p0**2/(2*MASS) + STIFFNESS*q0**2/2 - mechanical)/CAPACITY
    return q, p, theta, CAPACITY*np.log(theta/THETA_REF)


def run(tmp_path, name, model, initial, integrator):
    result, path = run_eme(tmp_path, name, {"model": {"model_name": "heat_bath", **model}, "initial": initial,
                                            "integrator": integrator})
    assert result.returncode == 0, result.stderr
    with h5py.File(path, "r") as f:
        return {key: f[key][()] for key in ("time", "state", "energy", "entropy", "temperature")}


@pytest.mark.parametrize("variable", VARIABLES)
def test_without_friction_eme_is_the_harmonic_oscillator(tmp_path, variable):
    """q, p against the closed form at second order (errors at dt and dt/2 in a ratio near 4), the
    temperature unchanged."""
    errors = []
    for dt in (0.02, 0.01):
        data = run(tmp_path, f"free_{dt}", {"friction": 0.0, "friction_cubic": 0.0},
                   {"q": 0.7, "p": 1.1, "theta_bath": 310.0}, {"thermo_variable": variable, "dt": dt, "t_end": 3.0})
        omega = np.sqrt(STIFFNESS/MASS)
        t = data["time"]
        q = 0.7*np.cos(omega*t) + 1.1/(MASS*omega)*np.sin(omega*t)
        p = MASS*(-0.7*omega*np.sin(omega*t) + 1.1/MASS*np.cos(omega*t))
        errors.append(max(np.max(np.abs(data["state"][:, 0] - q)), np.max(np.abs(data["state"][:, 1] - p))))
        assert np.max(np.abs(data["temperature"][:, 0] - 310.0)) < 1e-9
    # Midpoint-type phase error omega^3 t dt^2/12 |q|: about 1.2e-3 at dt = 0.02.
    assert errors[0] < 3e-3, errors
    assert 3.5 < errors[0]/errors[1] < 4.5, errors


@pytest.mark.parametrize("variable", VARIABLES)
def test_linear_drag_eme_is_the_damped_oscillator_heating_the_bath(tmp_path, variable):
    """q, p, theta and S against the closed form, converging at second order (dt = 0.01, 0.005 s)."""
    errors = []
    for dt in (0.01, 0.005):
        data = run(tmp_path, f"damped_{dt}", {"friction": 0.8, "friction_cubic": 0.0},
                   {"q": 1.0, "p": -0.5, "theta_bath": 290.0}, {"thermo_variable": variable, "dt": dt, "t_end": 4.0})
        q, p, theta, entropy = damped(data["time"], 1.0, -0.5, 290.0, 0.8)
        errors.append(np.array([np.max(np.abs(data["state"][:, 0] - q)), np.max(np.abs(data["state"][:, 1] - p)),
                                np.max(np.abs(data["temperature"][:, 0] - theta)),
                                np.max(np.abs(data["entropy"] - entropy))]))
        assert theta[-1] - theta[0] > 0.5          # the bath did warm by most of the 2.6 J
    # Measured at dt = 0.01: 1.3e-4 m, 1.2e-4 N s, 6e-5 K, 4e-7 J/K.
    assert np.all(errors[0] < [4e-4, 4e-4, 2e-4, 1.2e-6]), errors[0]
    assert np.all((3.5 < errors[0]/errors[1]) & (errors[0]/errors[1] < 4.5)), errors[0]/errors[1]


@pytest.mark.parametrize("variable", VARIABLES)
def test_every_integrator_keeps_energy_and_raises_entropy(tmp_path, variable):
    """The default scene (linear and cubic drag) on [0, 5] s, dt = 0.01 s: E = 602 J kept to 1e-13
    relative by the schemes that keep the structure (1e-5 relative, BDF2's 5e-4 J, by the others)
    and S never falls on a step (the others: by no more than 1e-8 J/K); every variable ends at the
    same entropy as EME in entropy variables (to 1e-7 J/K, BDF2 to 3e-6: the schemes' errors)."""
    reference = run(tmp_path, "reference", {}, {}, {"thermo_variable": "entropy", "dt": 0.01, "t_end": 5.0})
    assert reference["entropy"][-1] > 6e-3         # the 2 J of mechanical energy reached the bath
    for name, keeps_structure in integrators().items():
        data = run(tmp_path, name, {}, {}, {"scheme": name, "thermo_variable": variable, "dt": 0.01, "t_end": 5.0})
        energy, entropy = data["energy"], data["entropy"]
        drift = np.max(np.abs(energy - energy[0]))/energy[0]
        steps = np.diff(entropy)
        if keeps_structure:
            assert drift < 1e-13, (name, drift)
            assert np.all(steps >= 0.0), (name, steps.min())
        else:
            assert drift < 1e-5, (name, drift)
            assert np.all(steps >= -1e-8), (name, steps.min())
        # BDF2 (started by one first-order step) ends 9.5e-7 J/K off, every other within 1e-8.
        bound = 1e-7 if name != "ts_bdf2" else 3e-6
        assert abs(entropy[-1] - reference["entropy"][-1]) < bound, (name, entropy[-1], reference["entropy"][-1])
