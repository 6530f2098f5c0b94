"""The oracles of the spring ladder's lower rungs (tests/oracles/spring_ladder.py: the elastic and
the thermoelastic double spring pendulum, typed from docs/formulation.md and the paper's
definitions with SciPy) judged first by themselves, then against today's spatial
thermoviscoelastic model, which contains both rungs:

- thermoelastic = the full model with the viscous branch inert (beta_v = 0 and gamma = 0: gamma's
  rate is -2 mu_neq gamma/eta = 0 and its heating vanishes with it) and z components 0;
- elastic = the full model with beta = 0, mu_eq_slope = 0 and conductivity = 0: the spring force
  -(mu_eq(theta) L - beta (theta - theta_ref)) q/l^2 no longer depends on the temperatures, and the
  temperatures' rates -theta (mu_eq_slope L + beta) dL/dt + kappa (theta_b - theta_a) vanish, so
  the mechanics decouple (docs/formulation.md section 4's field with these parameters); started
  at theta_ref, the thermal energy Cap (theta - theta_ref) is 0 and E is the elastic energy.

relaxed_dp853 at tolerance 1e-12 against DOP853 at rtol = atol = 1e-12. Measured (2026-11-27):
Romero's scene over 30 s, largest error 2.2e-10 of each column's largest magnitude (6.6e-8 K of
the temperatures); the elastic scene over 10 s 1.2e-10 without gravity, 8.2e-11 with planar
gravity, 1.1e-11 with gravity off every axis; the oracle's own error, DOP853 at 1e-12 against
1e-13 or Radau, is of the same size (1.3e-10 to 5.8e-10). The tolerance, 1e-8 of each column's
scale, is 45 times the largest of these; the planted bugs of the last test move the oracle by at
least 10 times it. These tests run on today's code; tests/e2e/test_spring_ladder.py runs the
rungs themselves once `spring_law` and `dimension` exist.
"""
import sys
from dataclasses import replace
from pathlib import Path

import h5py
import numpy as np
import pytest

from conftest import ROOT, read_namelist, read_run, run_eme

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "oracles"))
import spring_ladder as oracle  # noqa: E402

TOLERANCE = 1e-8
# /state columns of the full model that a planar scene occupies (no z, no gamma), in the oracle's
# order q1, q2, p1, p2 (x, y each), then theta_1 theta_2 in the temperature variable.
PLANAR = ["q1_x", "q1_y", "q2_x", "q2_y", "p1_x", "p1_y", "p2_x", "p2_y"]
SPATIAL = ["q1_x", "q1_y", "q1_z", "q2_x", "q2_y", "q2_z", "p1_x", "p1_y", "p1_z", "p2_x", "p2_y", "p2_z"]
THERMAL = ["theta_1", "theta_2"]
ROMERO_END, GONZALEZ_END = 30.0, 10.0
# The elastic scene under three fields of gravity: none (E and J_z kept), in its plane, off every axis.
GRAVITIES = {"none": (0.0, 0.0), "planar": (0.0, -9.81), "oblique": (0.3, -2.0, -9.81)}


def columns(run, names):
    """The named /state columns of a run, as an array (rows, len(names))."""
    all_names = run["state_columns"]
    return run["state"][:, [all_names.index(name) for name in names]]


def run_full_model(tmp_path, name, model, initial, t_end, interval):
    """relaxed_dp853 at tolerance 1e-12 in the temperature variable, a row every `interval`."""
    result, path = run_eme(tmp_path, name, {
        "model": model, "initial": initial,
        "integrator": {"scheme": "relaxed_dp853", "thermo_variable": "temperature", "dt": interval,
                       "t_end": t_end, "tolerance": 1e-12},
        "output": {"interval": interval}})
    assert result.returncode == 0, result.stderr
    run = read_run(path)
    with h5py.File(path, "r") as f:
        run["state_columns"] = f["state"].attrs["columns"].split()
    return run


def relative_error(got, expected):
    """max |got - expected| over rows, per column divided by the column's largest |expected|."""
    return float(np.max(np.abs(got - expected) / np.abs(expected).max(axis=0)))


def gonzalez_with(gravity):
    """The elastic scene with another gravity (2 components planar, 3 spatial)."""
    return replace(oracle.GONZALEZ, gravity=gravity)


# ---------------------------------------------------------------- the oracles judge themselves
def test_the_thermoelastic_oracle_keeps_energy_and_momentum_and_produces_entropy():
    """Romero's scene over 30 s: E to 1e-10 relative, J (no gravity, planar: a scalar) to 1e-10
    relative, S rising between every pair of rows 0.3 s apart, by conduction alone."""
    times = np.arange(0.0, ROMERO_END + 1e-9, 0.3)
    states = oracle.reference(oracle.ROMERO, oracle.state_vector(oracle.ROMERO_INITIAL, 2, True), times, True)
    energy, entropy = np.array([oracle.thermoelastic_energy_entropy(oracle.ROMERO, y) for y in states]).T
    momentum = np.array([oracle.angular_momentum(oracle.ROMERO, y) for y in states])
    assert np.ptp(energy) < 1e-10 * abs(energy[0]), (np.ptp(energy), energy[0])
    assert np.ptp(momentum) < 1e-10 * abs(momentum[0]), (np.ptp(momentum), momentum[0])
    assert np.all(np.diff(entropy) > 0), np.diff(entropy).min()


@pytest.mark.parametrize("gravity", GRAVITIES)
def test_the_elastic_oracle_keeps_energy_and_the_momentum_its_gravity_allows(gravity):
    """E to 1e-10 relative under every gravity; J (2D, none) and J_z (3D, along z only) to 1e-10
    relative where the scene keeps them; where it does not, J moves (the check could fail)."""
    scene = gonzalez_with(GRAVITIES[gravity])
    y0 = oracle.state_vector({k: v + [0.0] for k, v in oracle.GONZALEZ_INITIAL.items()}, scene.dim, False)
    states = oracle.reference(scene, y0, np.linspace(0.0, GONZALEZ_END, 21), False)
    energy = np.array([oracle.elastic_energy(scene, y) for y in states])
    momentum = np.array([oracle.angular_momentum(scene, y) for y in states])
    assert np.ptp(energy) < 1e-10 * abs(energy[0]), (np.ptp(energy), energy[0])
    if gravity == "none":
        assert np.ptp(momentum) < 1e-10 * abs(momentum[0]), (np.ptp(momentum), momentum[0])
    else:
        assert np.ptp(momentum, axis=0).max() > 1.0, np.ptp(momentum, axis=0)


def test_the_dataset_convention_gives_the_projects_momenta():
    """q1 = x1, q2 = x2 - x1, p1 = P1 + P2, p2 = P2 (the issue's reading of the dataset) are the
    momenta conjugate to (q1, q2): T of the masses' own momenta equals 1/2 p.m^-1 p."""
    m1, m2 = oracle.ROMERO.mass
    x1, x2, P1, P2 = np.array([1.0, 2.0]), np.array([0.5, -1.0]), np.array([0.3, -0.7]), np.array([1.1, 0.4])
    q1, q2, p1, p2 = oracle.from_dataset(x1, x2, P1, P2)
    expected = 0.5 * P1 @ P1 / m1 + 0.5 * P2 @ P2 / m2
    got = oracle.kinetic_and_gravity(oracle.ROMERO, q1, q2, p1, p2)
    assert abs(got - expected) < 1e-15 * expected, (got, expected)
    np.testing.assert_allclose(q1 + q2, x2)


@pytest.mark.parametrize("name, scene, initial, law", [
    ("romero_thermoelastic", oracle.ROMERO, oracle.ROMERO_INITIAL, "thermoelastic"),
    ("gonzalez_elastic", oracle.GONZALEZ, oracle.GONZALEZ_INITIAL, "elastic")])
def test_the_published_inputs_state_the_oracles_scenes(name, scene, initial, law):
    """inputs/NAME.nml gives the scene the oracle integrates, number for number: its law, planar,
    and every parameter and initial value the rung has (and none it lacks)."""
    groups = read_namelist(ROOT / "inputs" / f"{name}.nml")
    model, start = groups["model"], groups["initial"]
    assert (model.pop("spring_law"), model.pop("dimension")) == (law, 2)
    expected = {"mass": list(scene.mass), "natural_length": list(scene.natural_length),
                "mu_eq_const": list(scene.mu_eq_const), "gravity": list(scene.gravity)}
    if law == "thermoelastic":
        expected.update(mu_eq_slope=list(scene.mu_eq_slope), beta=scene.beta,
                        heat_capacity=list(scene.heat_capacity), theta_ref=scene.theta_ref,
                        conductivity=scene.conductivity)
    assert model == expected, (model, expected)
    assert start == initial, (start, initial)


# ---------------------------------------------------------------- against today's full model
def test_thermoelastic_oracle_matches_the_full_model_with_an_inert_viscous_branch(tmp_path, eme_run_binary):
    """Romero's scene as the spatial thermoviscoelastic model: every 0.3 s to 30 s, q, p and the
    temperatures agree with the oracle to 1e-8 of each column's scale; gamma and the z components
    stay exactly 0; E and S at t = 0 agree to 1e-14 relative."""
    model, initial = oracle.full_model(oracle.ROMERO, oracle.ROMERO_INITIAL)
    run = run_full_model(tmp_path, "romero", model, initial, ROMERO_END, 0.3)
    expected = oracle.reference(oracle.ROMERO, oracle.state_vector(oracle.ROMERO_INITIAL, 2, True), run["time"], True)
    got = columns(run, PLANAR + THERMAL)
    error = relative_error(got, expected)
    assert error < TOLERANCE, f"got {error:.3g}, expected < {TOLERANCE:g}"
    assert not columns(run, ["q1_z", "q2_z", "p1_z", "p2_z", "gamma"]).any()
    energy, entropy = oracle.thermoelastic_energy_entropy(oracle.ROMERO, expected[0])
    assert abs(run["energy"][0] - energy) <= 1e-14 * abs(energy), (run["energy"][0], energy)
    assert abs(run["entropy"][0] - entropy) <= 1e-14 * abs(entropy), (run["entropy"][0], entropy)


@pytest.mark.parametrize("gravity", GRAVITIES)
def test_elastic_oracle_matches_the_full_model_without_thermal_coupling(tmp_path, eme_run_binary, gravity):
    """The elastic scene as the spatial model with beta = 0, mu_eq_slope = 0, conductivity = 0,
    started at theta_ref: every 0.5 s to 10 s, q and p agree with the oracle to 1e-8 of each
    column's scale, the temperatures stay exactly at theta_ref, and E(0) is the elastic energy to
    1e-14 relative (no thermal energy at theta_ref)."""
    scene = gonzalez_with(GRAVITIES[gravity])
    model, initial = oracle.full_model(scene, oracle.GONZALEZ_INITIAL, elastic=True)
    run = run_full_model(tmp_path, f"gonzalez_{gravity}", model, initial, GONZALEZ_END, 0.5)
    y0 = oracle.state_vector(initial, scene.dim, False)
    expected = oracle.reference(scene, y0, run["time"], False)
    got = columns(run, PLANAR if scene.dim == 2 else SPATIAL)
    error = relative_error(got, expected)
    assert error < TOLERANCE, f"got {error:.3g}, expected < {TOLERANCE:g}"
    assert np.all(columns(run, THERMAL) == scene.theta_ref)
    energy = oracle.elastic_energy(scene, y0)
    assert abs(run["energy"][0] - energy) <= 1e-14 * abs(energy), (run["energy"][0], energy)


# ---------------------------------------------------------------- the comparison can fail
def romero_bug(name):
    """Romero's scene with one plausible bug, as (scene, initial)."""
    scene, initial = oracle.ROMERO, dict(oracle.ROMERO_INITIAL)
    if name == "beta sign":
        scene = replace(scene, beta=-scene.beta)
    elif name == "heat capacities halved":
        scene = replace(scene, heat_capacity=tuple(c / 2 for c in scene.heat_capacity))
    elif name == "conductivity / 10":
        scene = replace(scene, conductivity=scene.conductivity / 10)
    elif name == "masses swapped":
        scene = replace(scene, mass=scene.mass[::-1])
    elif name == "stiffnesses swapped":
        scene = replace(scene, mu_eq_const=scene.mu_eq_const[::-1])
    elif name == "absolute q2":
        initial["q2"] = list(np.add(initial["q1"], initial["q2"]))
    elif name == "p1 as mass 1's own":
        initial["p1"] = list(np.subtract(initial["p1"], initial["p2"]))
    return scene, initial


ROMERO_BUGS = ["beta sign", "heat capacities halved", "conductivity / 10", "masses swapped", "stiffnesses swapped",
               "absolute q2", "p1 as mass 1's own"]


@pytest.mark.parametrize("bug", ROMERO_BUGS)
def test_the_comparison_sees_these_bugs(bug):
    """Each plausible bug (a parameter's sign or size, the state convention) moves Romero's
    reference at the compared times by more than 10 times the tolerance."""
    times = np.arange(0.0, ROMERO_END + 1e-9, 0.3)
    right = oracle.reference(oracle.ROMERO, oracle.state_vector(oracle.ROMERO_INITIAL, 2, True), times, True)
    scene, initial = romero_bug(bug)
    wrong = oracle.reference(scene, oracle.state_vector(initial, 2, True), times, True)
    moved = relative_error(wrong, right)
    assert moved > 10 * TOLERANCE, f"{bug}: moved {moved:.3g}, expected > {10 * TOLERANCE:g}"
