"""The spring chain's physics checked on runs of the code (issue 39 item 6; docs/formulation.md
section 10, "Exact linear modes" and "The end state of an isolated chain"). The expected values
come from tests/oracles/spring_chain.py, typed from section 10 in numpy (not from src/):

- exact linear modes: a 1D 'fixed-fixed' chain of identical springs started in one mode at small
  amplitude about its uniform stretch follows, step by step, the midpoint rule's map of the
  linearised system, (I - dt A_k/2)^-1 (I + dt A_k/2) per mode; the run's deviation from it,
  relative to the mode's size, is of the order of the amplitude and halves with it (the
  nonlinear terms' order), on eme_run (N = 8, 50) and chain_bench (N = 2000), in the three rungs
  and the three thermodynamic variables;
- the end state of an isolated chain: a long EME run of a small dissipative chain, started moving,
  unevenly stretched and at unlike temperatures, ends at rest with equal springs, relaxed dampers
  and the one temperature its energy fixes, its entropy rising to that state's and not beyond;
- every step of a 200-spring run on eme_run: energy to 1e-13 relative, V never rising, every
  viscous branch's and every link's entropy production >= 0 at every written state, and each
  spring's entropy increment equal to its production and heat received integrated over the step
  (to the trapezoidal rule's accuracy).
"""
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import h5py
import numpy as np
import pytest
from scipy.linalg import expm

from conftest import BIN, namelist_text, run_eme

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "oracles"))
import spring_chain as oracle  # noqa: E402

# One spring's data per rung: stiff enough that the axial modes, the damper and the heat modes all
# act within a few steps; beta and mu_eq_slope couple displacement to temperature, beta_v to the
# damper (the free energy stays convex at the uniform stretch: 2 (1 + beta_v) mu^neq > beta_v^2 mu/l^2).
SPRINGS = {
    "elastic": oracle.Spring(natural_length=0.5, mu_eq_const=80.0),
    "thermoelastic": oracle.Spring(natural_length=0.5, mu_eq_const=80.0, mu_eq_slope=0.1, beta=0.8,
                                   heat_capacity=3.0),
    "thermoviscoelastic": oracle.Spring(natural_length=0.5, mu_eq_const=80.0, mu_eq_slope=0.1, beta=0.8,
                                        heat_capacity=3.0, beta_v=0.4, mu_neq_const=30.0, mu_neq_slope=0.02,
                                        viscosity_const=2.0, viscosity_activation=10.0)}
RUNG_FIELDS = {
    "elastic": ["natural_length", "mu_eq_const"],
    "thermoelastic": ["natural_length", "mu_eq_const", "mu_eq_slope", "beta", "heat_capacity", "theta_ref"],
    "thermoviscoelastic": ["natural_length", "mu_eq_const", "mu_eq_slope", "beta", "heat_capacity", "theta_ref",
                           "beta_v", "mu_neq_const", "mu_neq_slope", "viscosity_const", "viscosity_activation"]}
MASS = 0.3          # kg
KAPPA = 2.5         # W/K, every link
STRETCH = 1.05      # the uniform stretch l_s/l^0
THETA0 = 300.0      # K, the base temperature (theta_ref: the elastic rung's springs are at it)


def uniform_chain(n, law, kappa=KAPPA, mass=MASS, stretch=STRETCH, **spring_changes):
    """The oracle's 1D 'fixed-fixed' chain of n masses and n + 1 identical springs of rung `law`."""
    spring = replace(SPRINGS[law], **spring_changes)
    return oracle.Chain(masses=np.full(n, mass), springs=[spring] * (n + 1),
                        conductivity=np.full(n, kappa if law != "elastic" else 0.0), gravity=[0.0],
                        ends="fixed-fixed", span=(n + 1) * spring.natural_length * stretch)


def model_group(chain, law):
    """The &model group of the oracle's uniform chain (one value for every spring)."""
    spring = chain.springs[0]
    group = {"model_name": "spring_chain", "links": chain.n, "ends": "fixed-fixed", "span": chain.span,
             "dimension": 1, "gravity": [0.0], "spring_law": law, "mass": float(chain.masses[0])}
    group.update({name: float(getattr(spring, name)) for name in RUNG_FIELDS[law]})
    if law != "elastic":
        group["conductivity"] = float(chain.conductivity[0])
    return group


def integrator_group(law, variable, dt, steps, newton_tol=1e-13, gradient="gonzalez"):
    group = {"scheme": "eme", "dt": dt, "t_end": dt * steps, "newton_tol": newton_tol,
             "discrete_gradient": gradient}
    if law != "elastic":
        group["thermo_variable"] = variable
    return group


def text(value):
    return value.decode() if isinstance(value, bytes) else str(value)


def read_chain_rows(path, chain, law):
    """(x (rows, N), p (rows, N), gamma (rows, ns), theta (rows, ns)) of a 1D chain's run file, by
    column name; gamma 0 and theta THETA0 where the rung has none."""
    with h5py.File(path, "r") as f:
        assert text(f.attrs["status"]) == "complete"
        names = [text(c) for c in f["state_column"][()]]
        state = f["state"][()]
        rows = state.shape[0]
        x = state[:, [names.index(f"x{i}_x") for i in range(1, chain.n + 1)]]
        p = state[:, [names.index(f"p{i}_x") for i in range(1, chain.n + 1)]]
        gamma = (state[:, [names.index(f"gamma_{a}") for a in range(1, chain.ns + 1)]]
                 if law == "thermoviscoelastic" else np.zeros((rows, chain.ns)))
        theta = f["temperature"][()] if law != "elastic" else np.full((rows, chain.ns), THETA0)
        series = {name: f[name][()] for name in ("time", "energy")}
        if law != "elastic":
            series.update({name: f[name][()] for name in ("entropy", "lyapunov")})
    return x, p, gamma, theta, series


# ---------------------------------------------------------------- exact linear modes
def propagate(chain, nodal_start, modes, steps, propagator):
    """The nodal deviations (u, p, g, T) at steps 0..steps from `nodal_start`, which lies in
    `modes` (section 10's sine and cosine modes), each mode's amplitudes moved by propagator(A_k,
    step), A_k from the oracle's second derivatives of psi at the base state."""
    c = oracle.linear_coefficients(chain, THETA0)
    rows = np.zeros((steps + 1, len(nodal_start)))
    for k in modes:
        a_k = oracle.mode_generator(c, chain.n, k)
        zeta = oracle.modal_amplitudes(chain.n, nodal_start, k)
        for row in range(steps + 1):
            rows[row] += oracle.mode_state(chain.n, k, propagator(a_k, row) @ zeta)
    return rows


def midpoint_map(dt):
    """The midpoint rule's map of dz/dt = A z, step times: the Cayley transform's power."""
    return lambda a_k, step: np.linalg.matrix_power(oracle.cayley(a_k, dt), step)


def exact_map(dt):
    """The linear system's exact flow over step dt: to show that a run follows the step map and
    not merely the equations."""
    return lambda a_k, step: expm(step * dt * a_k)


def relative_deviation(got, expected, n):
    """max over the rows of |got - expected| per field (u, p, g, T), each relative to the largest
    magnitude that field's expected rows reach (fields that stay 0, as an elastic chain's g and T,
    are left out)."""
    fields = [slice(0, n), slice(n, 2 * n), slice(2 * n, 3 * n + 1), slice(3 * n + 1, 4 * n + 2)]
    deviations = []
    for field in fields:
        scale = np.abs(expected[:, field]).max()
        if scale > 0:
            deviations.append(np.abs(got[:, field] - expected[:, field]).max() / scale)
    return max(deviations)


def nodal_deviations(chain, gamma0, x, p, gamma, theta):
    """Rows of (u, p, g, T): the state's deviation from the uniform stretch."""
    l_s = chain.span / chain.ns
    return np.hstack([x - np.arange(1, chain.n + 1) * l_s, p, gamma - gamma0, theta - THETA0])


def mode_file(path, chain, gamma0, nodal):
    """An &initial file holding the base state plus the nodal deviation (u, p, g, T)."""
    n = chain.n
    l_s = chain.span / chain.ns
    with h5py.File(path, "w") as f:
        f["q"] = (np.arange(1, n + 1) * l_s + nodal[:n])[:, None]
        f["p"] = nodal[n:2 * n][:, None]
        f["gamma"] = gamma0 + nodal[2 * n:3 * n + 1]
        f["theta"] = THETA0 + nodal[3 * n + 1:]


def start(chain, law, gamma0, amplitude, mode, directory):
    """&initial for a run started in mode `mode` at `amplitude` (m), and the modes it excites:
    mode k >= 1 by perturbation = 'mode' (the masses moved along x by amplitude sin(k pi i/(N + 1)));
    ('file', k) by an &initial file with every amplitude of mode k (U, P, G, Theta) and mode 0's
    (G, Theta) nonzero."""
    initial = {"theta": THETA0} if law != "elastic" else {}
    if law == "thermoviscoelastic":
        initial["gamma"] = float(gamma0)
    if not isinstance(mode, tuple):
        initial.update(perturbation="mode", mode_number=mode, amplitude=amplitude)
        return initial, [mode]
    k = mode[1]
    n = chain.n
    c = oracle.linear_coefficients(chain, THETA0)
    omega = 2 * np.sin(k * np.pi / (2 * (n + 1))) * np.sqrt(c["ll"] / c["m"])
    # U, P (a quarter period on), G, Theta of mode k and G, Theta of mode 0, each of the size one
    # displacement of `amplitude` gives it (Theta: the adiabatic heating of such a strain, ~ 20 K/m).
    nodal = (oracle.mode_state(n, k, amplitude * np.array([1.0, 0.7 * c["m"] * omega, -0.4, 25.0]))
             + oracle.mode_state(n, 0, amplitude * np.array([0.3, -15.0])))
    mode_file(directory / "start.h5", chain, gamma0, nodal)
    return {"file": str(directory / "start.h5")}, [0, k]


LINEAR_CASES = [  # (N, rung, variable, discrete gradient, mode, dt, steps)
    (8, "elastic", "temperature", "gonzalez", 3, 0.05, 30),
    (8, "thermoelastic", "entropy", "gonzalez", 2, 0.05, 30),
    (8, "thermoviscoelastic", "temperature", "gonzalez", 1, 0.05, 30),
    (8, "thermoviscoelastic", "entropy", "partitioned", ("file", 4), 0.05, 30),
    (50, "thermoviscoelastic", "internal_energy", "partitioned", 7, 0.05, 20),
]
AMPLITUDE = 2.5e-4      # m: 5e-4 of the springs' length


def assert_runs_follow_the_midpoint_map(label, chain, run, dt, steps):
    """For eps = AMPLITUDE and eps/2, run(eps) gives (the steps written, the state's deviations
    (u, p, g, T) at them, the modes it started in): each deviates from the per-mode Cayley map's
    prediction by less than 3 eps/l_s relative (relative_deviation), the two deviations are 1.8 to
    2.2 apart, and the linearised system's exact flow is at least 5 times that bound away from the
    prediction."""
    l_s = chain.span / chain.ns
    deviations = []
    for amplitude in (AMPLITUDE, AMPLITUDE / 2):
        written, got, modes = run(amplitude)
        expected = propagate(chain, got[0], modes, steps, midpoint_map(dt))[written]
        flow = relative_deviation(propagate(chain, got[0], modes, steps, exact_map(dt))[written], expected, chain.n)
        deviations.append(relative_deviation(got, expected, chain.n))
        bound = 3 * amplitude / l_s
        print(f"{label}: eps/l_s = {amplitude / l_s:.3g}, relative deviation {deviations[-1]:.3g} "
              f"(exact flow {flow:.3g})")
        assert deviations[-1] < bound, (deviations[-1], amplitude / l_s)
        assert flow > 5 * bound, flow
    assert 1.8 < deviations[0] / deviations[1] < 2.2, deviations


@pytest.mark.parametrize("n, law, variable, gradient, mode, dt, steps", LINEAR_CASES,
                         ids=lambda v: "-".join(map(str, v)) if isinstance(v, tuple) else str(v))
def test_a_mode_follows_the_midpoint_map_of_the_linearised_chain(tmp_path, n, law, variable, gradient, mode, dt, steps):
    """eme_run from the uniform stretch plus one mode at amplitude eps and eps/2: every written
    state's deviation (u, p, g, T) equals the per-mode Cayley map's prediction to a relative error
    below 3 eps/l_s that halves with eps (1.8 to 2.2), while the linearised system's exact flow is
    at least 5 times farther from the prediction (the run follows the step map, not only the
    equations). Measured: 0.38 to 1.3 eps/l_s, ratios 2.00 (docs/formulation.md section 10).
    Planted bugs it catches: twice the links' heat flow (spring_chain_blocks' link_block), a step
    residual of 0.9 dt (step_residual)."""
    chain = uniform_chain(n, law)
    _, gamma0, _ = oracle.base_state(chain, THETA0)

    def run(amplitude):
        directory = tmp_path / f"eps{amplitude:g}"
        directory.mkdir()
        initial, modes = start(chain, law, gamma0, amplitude, mode, directory)
        groups = {"model": model_group(chain, law), "initial": initial,
                  "integrator": integrator_group(law, variable, dt, steps, gradient=gradient)}
        result, path = run_eme(directory, "mode", groups, "-eme_dense")
        assert result.returncode == 0, result.stderr
        got = nodal_deviations(chain, gamma0, *read_chain_rows(path, chain, law)[:4])
        assert got.shape[0] == steps + 1
        return np.arange(steps + 1), got, modes

    assert_runs_follow_the_midpoint_map(f"N={n} {law} {variable} mode {mode}", chain, run, dt, steps)


def test_a_mode_of_a_long_chain_on_the_sparse_path_follows_the_midpoint_map(tmp_path):
    """chain_bench (sparse), N = 2000 masses, thermoviscoelastic springs in the temperature
    variable, mode 1000 (dt omega_k = 2.6) at eps and eps/2: the snapshots every 5 of 10 steps
    equal the per-mode Cayley map's prediction to below 3 eps/l_s relative, halving with eps (1.8
    to 2.2). Measured 1.4 eps/l_s, ratio 2.00; twice the links' heat flow (planted) gives 0.25. One
    rank: two agree with one to 1e-10 (test_spring_chain_sparse.py) and cost 8 times the wall time
    here."""
    n, law, k, dt, steps, every = 2000, "thermoviscoelastic", 1000, 0.05, 10, 5
    chain = uniform_chain(n, law)
    _, gamma0, _ = oracle.base_state(chain, THETA0)

    def run(amplitude):
        initial, modes = start(chain, law, gamma0, amplitude, k, tmp_path)
        name = f"eps{amplitude:g}"
        groups = {"model": model_group(chain, law), "initial": initial,
                  "integrator": integrator_group(law, "temperature", dt, steps),
                  "output": {"file": str(tmp_path / f"{name}.h5")}}
        namelist = tmp_path / f"{name}.nml"
        namelist.write_text(namelist_text(groups))
        snapshots = tmp_path / f"{name}_snapshots.h5"
        result = subprocess.run([str(BIN / "chain_bench"), str(namelist),
                                 "-chain_snapshots", str(snapshots), "-chain_snapshot_every", str(every)],
                                capture_output=True, text=True, timeout=600)
        assert result.returncode == 0, result.stderr
        with h5py.File(snapshots, "r") as f:
            written = np.rint(f["snapshots/time"][()] / dt).astype(int)
            got = nodal_deviations(chain, gamma0, f["snapshots/q"][:, :, 0], f["snapshots/p"][:, :, 0],
                                   f["snapshots/gamma"][()], f["snapshots/theta"][()])
        assert np.array_equal(written, np.arange(0, steps + 1, every)), written
        return written, got, modes

    assert_runs_follow_the_midpoint_map(f"N={n} mode {k} on chain_bench", chain, run, dt, steps)


# ---------------------------------------------------------------- the end state of an isolated chain
def flat_states(x, p, gamma, theta):
    """The oracle's flat states (x, p, gamma, theta) of each row of a 1D chain's run."""
    return np.hstack([x, p, gamma, theta])


def test_an_isolated_chain_ends_in_the_state_its_energy_fixes(tmp_path):
    """A 1D 'fixed-fixed' chain of 6 masses and 7 identical thermoviscoelastic springs, well
    conducting, no gravity, started moving, unevenly stretched, its dampers strained and its springs
    at 270 to 350 K, run by EME (temperature variable) for 300 steps of 0.075 s. The end state of
    section 10, solved here from E_0 = 7 u(l*, theta*, gamma*(theta*)) (tests/oracles/
    spring_chain.py): at rest, every spring of length span/7, relaxed dampers, one temperature
    theta*. The run's first E and S are the oracle's E(z_0), S(z_0) (1e-13), E stays (1e-12), S
    never falls (beyond 4 n_s Cap eps, its rounding) and ends at S* within 1e-9 (S* - S_0), never above S* by more
    than the run's energy error over theta* (plus rounding), and the last state is the end state
    (positions 1e-9 l*, momenta 1e-9 of the initial ones, gamma 1e-9 of its initial spread,
    temperatures 1e-8 K). beta_v = 0.2 here: with the mode tests' 0.4 such a start collapses a
    spring (psi is unbounded below as l -> 0, docs/formulation.md section 10). Planted: the links'
    conductivity not reaching the model (spring_chain_initial) leaves the springs 25 K apart."""
    n, law, dt, steps = 6, "thermoviscoelastic", 0.075, 300
    chain = uniform_chain(n, law, kappa=100.0, beta_v=0.2)
    l_s = chain.span / chain.ns
    rng = np.random.default_rng(39)
    x0 = np.arange(1, n + 1) * l_s + 0.08 * l_s * rng.uniform(-1, 1, n)
    p0 = 0.3 * rng.uniform(-1, 1, n)
    gamma_start = 0.01 * rng.uniform(-1, 1, n + 1)
    theta_start = np.linspace(270.0, 350.0, n + 1)[rng.permutation(n + 1)]
    y0 = oracle.join(x0[:, None], p0[:, None], gamma_start, theta_start)
    energy0, entropy0 = oracle.energy_entropy(chain, y0)
    y_star, theta_star, entropy_star = oracle.end_state(chain, energy0)
    groups = {"model": model_group(chain, law),
              "initial": {"x": list(x0), "p": list(p0), "gamma": list(gamma_start), "theta": list(theta_start)},
              "integrator": integrator_group(law, "temperature", dt, steps)}
    result, path = run_eme(tmp_path, "isolated", groups)
    assert result.returncode == 0, result.stderr
    x, p, gamma, theta, series = read_chain_rows(path, chain, law)
    energy, entropy = series["energy"], series["entropy"]
    off = np.abs(flat_states(x, p, gamma, theta)[-1] - y_star).max()
    print(f"theta* = {theta_star:.6f} K, S* - S_0 = {entropy_star - entropy0:.6g} J/K; after {steps} steps: "
          f"S* - S = {entropy_star - entropy[-1]:.3g}, largest S - S* {np.max(entropy - entropy_star):.3g}, "
          f"|E - E_0| {np.max(np.abs(energy - energy0)):.3g}, state off by {off:.3g}")
    assert abs(energy[0] - energy0) <= 1e-13 * abs(energy0), (energy[0], energy0)
    assert abs(entropy[0] - entropy0) <= 1e-13 * abs(entropy0), (entropy[0], entropy0)
    energy_error = np.max(np.abs(energy - energy0))
    assert energy_error <= 1e-12 * abs(energy0), energy_error
    # S's rounding: each temperature's ulp moves s_a by Cap eps (section 3: s = sigma + Cap ln theta).
    rounding = 4 * chain.ns * oracle.capacity(oracle.spring_arrays(chain)).max() * np.finfo(float).eps
    assert np.all(np.diff(entropy) >= -rounding), np.diff(entropy).min()
    assert abs(entropy_star - entropy[-1]) <= 1e-9 * (entropy_star - entropy0)
    assert np.max(entropy - entropy_star) <= energy_error / theta_star + rounding
    _, _, gamma_end, theta_end = oracle.split(chain, y_star)
    assert np.max(np.abs(x[-1] - y_star[:n])) <= 1e-9 * l_s
    assert np.max(np.abs(p[-1])) <= 1e-9 * np.max(np.abs(p0))
    assert np.max(np.abs(gamma[-1] - gamma_end)) <= 1e-9 * np.ptp(gamma_start)
    assert np.max(np.abs(theta[-1] - theta_end)) <= 1e-8


# ---------------------------------------------------------------- every step of a 200-spring chain
def spring_entropy_gradient(chain, before, after):
    """Section 5's Gonzalez discrete gradient of each spring's entropy s_a(C_a, gamma_a, u_a) between
    two states (x, gamma, u) of a 1D chain run in the internal energy, with section 5's metric (C by
    (l^0)^2, gamma by 1 m, u by Cap theta_ref; the midpoint gradient below eps^(2/3)), typed from the
    docs: s_a's partials are -psi_l/(2 l theta), -psi_gamma/theta and 1/theta (Gibbs), theta from
    u = u(theta_ref) + Cap (theta - theta_ref). Returns (D s (3, ns), the change of each s_a)."""
    k = oracle.spring_arrays(chain)
    cap = oracle.capacity(k)

    def invariants(state):
        x, gamma, u = state
        length = oracle.spring_vectors(chain, x[:, None])[1]
        return np.stack([length**2, gamma, u])

    def entropy_temperature(z):
        length, gamma = np.sqrt(z[0]), z[1]
        theta = k["theta_ref"] + (z[2] - oracle.entropy_energy(k, length, k["theta_ref"], gamma)[1]) / cap
        return oracle.entropy_energy(k, length, theta, gamma)[0], theta

    def gradient(z):
        length, theta = np.sqrt(z[0]), entropy_temperature(z)[1]
        psi_l, _, psi_gamma = oracle.psi_gradient(k, length, theta, z[1])
        return np.stack([-psi_l / (2 * length * theta), -psi_gamma / theta, 1 / theta])

    a, b = invariants(before), invariants(after)
    d = b - a
    change = entropy_temperature(b)[0] - entropy_temperature(a)[0]
    midpoint = gradient((a + b) / 2)
    weight = np.stack([k["natural_length"]**-4, np.ones(chain.ns), (cap * k["theta_ref"])**-2])
    metric = np.sum(weight * d * d, axis=0)
    correction = np.where(np.sqrt(metric) < np.finfo(float).eps**(2 / 3), 0.0,
                          (change - np.sum(midpoint * d, axis=0)) / np.maximum(metric, np.finfo(float).tiny))
    return midpoint + correction * weight * d, change


def test_every_step_of_a_200_spring_chain_keeps_each_balance(tmp_path):
    """eme_run (dense) on a 1D 'fixed-fixed' chain of 199 masses and 200 thermoviscoelastic springs
    (798 unknowns), temperatures alternating 40 K apart on a gradient, the masses moved into mode 3,
    8 steps of 0.0025 s in the internal-energy variable. Every step: |E_{n+1} - E_n| <= 1e-13 |E|,
    V never rises, and, from this test's own Gonzalez discrete gradient of each spring's entropy
    (section 5, in u_a the discrete temperature is Theta_a = 1/D_u s_a): every Theta_a > 0, so that
    each viscous branch's production Theta_a y_a^2/eta_a(Theta_a) and each link's kappa (Theta_a -
    Theta_b)^2/(Theta_a Theta_b) is >= 0; each damper moves as the step says, dgamma_a/dt =
    Theta_a y_a/eta_a with y_a = D_gamma s_a, to 1e-9 of the largest rate; and each spring's entropy
    changes by exactly dt (its viscous production + its heat received over Theta_a), to 1e-9 of the
    largest term: every branch and every link acts with its own size and sign (section 10's Delta S,
    spring by spring). Planted: twice the links' heat flow (spring_chain_blocks' link_block) breaks
    the spring balance while E, V and the damper rates still pass; the midpoint gradient without
    Gonzalez's correction in the code breaks the damper rates."""
    n, law, dt, steps = 199, "thermoviscoelastic", 0.0025, 8
    chain = uniform_chain(n, law)
    _, gamma0, _ = oracle.base_state(chain, THETA0)
    theta_start = 300.0 + 20.0 * np.linspace(-1, 1, n + 1) + 20.0 * (-1.0) ** np.arange(n + 1)
    groups = {"model": model_group(chain, law),
              "initial": {"gamma": float(gamma0), "theta": list(theta_start), "perturbation": "mode",
                          "mode_number": 3, "amplitude": 0.02},
              "integrator": integrator_group(law, "internal_energy", dt, steps, newton_tol=1e-11)}
    result, path = run_eme(tmp_path, "steps", groups, "-eme_dense")
    assert result.returncode == 0, result.stderr
    x, _, gamma, _, series = read_chain_rows(path, chain, law)
    with h5py.File(path, "r") as f:
        names = [text(c) for c in f["state_column"][()]]
        u = f["state"][()][:, [names.index(f"u_{a}") for a in range(1, chain.ns + 1)]]
    energy, lyapunov = series["energy"], series["lyapunov"]
    assert len(energy) == steps + 1
    energy_steps = np.abs(np.diff(energy)) / np.abs(energy[1:])
    assert np.max(energy_steps) <= 1e-13, energy_steps
    assert np.all(np.diff(lyapunov) <= 0), np.diff(lyapunov).max()
    k = oracle.spring_arrays(chain)
    worst_rate = worst_balance = 0.0
    lowest_theta = lowest_viscous = lowest_link = np.inf
    for row in range(steps):
        gradient, change = spring_entropy_gradient(chain, (x[row], gamma[row], u[row]),
                                                   (x[row + 1], gamma[row + 1], u[row + 1]))
        theta = 1 / gradient[2]
        lowest_theta = min(lowest_theta, theta.min())
        assert np.all(theta > 0), (row, theta.min())
        eta = oracle.viscosity(k, theta)
        rate = theta * gradient[1] / eta
        worst_rate = max(worst_rate, np.max(np.abs((gamma[row + 1] - gamma[row]) / dt - rate)) / np.abs(rate).max())
        viscous = theta * gradient[1]**2 / eta
        received = oracle.conduction(chain, theta) / theta
        links = chain.conductivity * (theta[:-1] - theta[1:])**2 / (theta[:-1] * theta[1:])
        lowest_viscous, lowest_link = min(lowest_viscous, viscous.min()), min(lowest_link, links.min())
        scale = dt * max(viscous.max(), np.abs(received).max())
        worst_balance = max(worst_balance, np.max(np.abs(change - dt * (viscous + received))) / scale)
    print(f"largest step |dE|/|E| {energy_steps.max():.3g}, largest dV {np.diff(lyapunov).max():.3g} J, "
          f"lowest discrete temperature {lowest_theta:.6g} K, smallest viscous production {lowest_viscous:.3g} W/K, "
          f"link {lowest_link:.3g} W/K; damper rates off by {worst_rate:.3g}, spring entropy balances by "
          f"{worst_balance:.3g} of their largest term")
    assert worst_rate <= 1e-9, worst_rate
    assert worst_balance <= 1e-9, worst_balance
