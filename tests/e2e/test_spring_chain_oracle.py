"""The spring chain's oracle (tests/oracles/spring_chain.py, typed from docs/formulation.md section
10) judged by itself and against the project's pendulum:

- its derivatives of psi against complex steps of psi as eq. (16) prints it;
- along a SciPy solution of a hanging 3D chain of five unlike springs E and the conserved J stay,
  S rises, every viscous branch and link produces entropy;
- N = 2 'fixed-free' in 3D with Table 1 is the paper's pendulum: E and S at t = 0 equal eme_run's
  on inputs/paper_fig4_eme_theta.nml, and a relaxed_rk8 run's state at 2 s, converted to the chain's
  absolute coordinates, equals the oracle's;
- the nodal linearisation equals the oracle field's Jacobian at the uniform stretch, and the
  closed-form step map per mode (the Cayley transform of A_k) equals a direct implicit-midpoint
  solve of the whole linearised system, for several N, modes and parameter sets;
- a long SciPy run of a small isolated chain ends in the end state the section predicts;
- the continuum family's values scale as its table says, its heat modes tend to the rod's, and its
  stiffest eigenvalue grows like N^2.
"""
import sys
from dataclasses import replace
from pathlib import Path

import h5py
import numpy as np
import pytest

from conftest import ROOT, read_namelist, read_run, run_eme

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "oracles"))
import spring_chain as oracle  # noqa: E402

# Unlike springs of the paper's law (each field differs from spring to spring) for the hanging chain.
UNLIKE = [oracle.Spring(natural_length=0.4 + 0.05 * a, mu_eq_const=150.0 + 20 * a, mu_eq_slope=0.3 + 0.05 * a,
                        beta=0.02 + 0.01 * a, heat_capacity=4.0 + a, beta_v=0.2 * (a % 3), mu_neq_const=4.0 + a,
                        mu_neq_slope=0.05 * (a % 2), viscosity_const=20.0 + 5 * a, viscosity_activation=8.0)
          for a in range(5)]


def hanging_chain():
    """Five masses hanging in 3D from unlike springs, unlike links, started off the vertical, moving and
    at unlike temperatures."""
    chain = oracle.Chain(masses=[1.0, 0.7, 1.3, 0.9, 1.1], springs=UNLIKE,
                         conductivity=[0.5, 2.0, 1.0, 3.0], gravity=[0.0, 0.0, -9.81])
    x = np.cumsum([[0.3, 0.1, -0.4], [0.2, -0.3, -0.3], [-0.2, 0.2, -0.5], [0.1, 0.3, -0.4], [0.3, -0.1, -0.5]], axis=0)
    p = np.array([[0.0, 1.0, 0.0], [0.5, 0.0, 0.2], [0.0, -1.0, 0.0], [0.3, 0.3, 0.0], [-0.5, 0.0, 0.1]])
    return chain, oracle.join(x, p, [0.0, 0.05, -0.02, 0.0, 0.03], [290.0, 320.0, 300.0, 340.0, 280.0])


# ---------------------------------------------------------------- the oracle judges itself
def test_psi_derivatives_are_those_of_psi():
    """psi_l, psi_theta and psi_gamma as section 10 types them equal complex steps of psi (16)-(17),
    on every unlike spring at unlike lengths, temperatures and damper elongations."""
    k = oracle.spring_arrays(hanging_chain()[0])
    l, theta, gamma = np.array([0.3, 0.6, 0.45, 0.9, 0.5]), np.array([250.0, 300.0, 330.0, 280.0, 400.0]), \
        np.array([0.1, -0.2, 0.0, 0.3, 0.05])
    gradient = oracle.psi_gradient(k, l, theta, gamma)
    for j, name in enumerate(["l", "theta", "gamma"]):
        args = [l.astype(complex), theta.astype(complex), gamma.astype(complex)]
        args[j] = args[j] + 1j * oracle.COMPLEX_STEP
        expected = np.imag(oracle.psi(k, *args)) / oracle.COMPLEX_STEP
        np.testing.assert_allclose(gradient[j], expected, rtol=1e-13, atol=1e-13, err_msg=f"psi_{name}")
    # Cap = -theta psi_theta_theta = (1 + beta_v) c
    np.testing.assert_allclose(-theta * oracle.psi_hessian(k, l, theta, gamma)[1][1], oracle.capacity(k), rtol=1e-13)


def test_the_oracle_keeps_energy_and_momentum_and_every_branch_produces_entropy():
    """The hanging chain over 3 s (DOP853 at 1e-12): E and J_z (about gravity) to 1e-10 relative,
    S rising between rows 0.1 s apart, each viscous branch's and each link's production >= 0, > 0
    for every link and every damper that moves (springs 1 and 4 have none that does: beta_v = 0 and
    gamma = 0), and the momentum gravity does not keep (J_x) moving."""
    chain, y0 = hanging_chain()
    states = oracle.solve(chain, y0, np.arange(0.0, 3.0 + 1e-9, 0.1))
    energy, entropy = np.array([oracle.energy_entropy(chain, y) for y in states]).T
    momentum = np.array([oracle.conserved_momenta(chain, y) for y in states])
    assert np.ptp(energy) < 1e-10 * abs(energy[0]), (np.ptp(energy), energy[0])
    assert momentum.shape[1] == 1 and np.ptp(momentum) < 1e-10 * np.abs(momentum).max(), momentum
    assert np.all(np.diff(entropy) > 0), np.diff(entropy).min()
    productions = np.array([np.concatenate(oracle.entropy_production(chain, y)) for y in states])
    assert np.all(productions >= 0) and np.all(productions.max(axis=0)[[1, 2, 4, 5, 6, 7, 8]] > 0)
    assert np.all(productions[:, [0, 3]] == 0), productions[:, [0, 3]].max()
    assert np.ptp([oracle.angular_momentum(chain, y)[0] for y in states]) > 0.1


# ---------------------------------------------------------------- N = 2 is the paper's pendulum
PENDULUM_COLUMNS = ["q1_x", "q1_y", "q1_z", "q2_x", "q2_y", "q2_z", "p1_x", "p1_y", "p1_z", "p2_x", "p2_y", "p2_z",
                    "gamma", "theta_1", "theta_2"]


def chain_state_of_pendulum_row(row):
    """The chain's flat state from a pendulum /state row in the temperature variable."""
    q1, q2, p1, p2 = row[0:3], row[3:6], row[6:9], row[9:12]
    return oracle.join(*oracle.from_pendulum(q1, q2, p1, p2), [0.0, row[12]], row[13:15])


def test_n2_chain_has_the_paper_pendulums_energy_and_entropy(tmp_path, eme_run_binary):
    """E and S at t = 0 of inputs/paper_fig4_eme_theta.nml's run (one step of it) equal the N = 2
    chain's to 1e-14 relative, and its first /state row is the chain's initial state converted."""
    groups = read_namelist(ROOT / "inputs" / "paper_fig4_eme_theta.nml")
    groups["integrator"]["t_end"] = groups["integrator"]["dt"]
    result, path = run_eme(tmp_path, "paper", groups)
    assert result.returncode == 0, result.stderr
    run = read_run(path)
    energy, entropy = oracle.energy_entropy(oracle.paper_chain(), oracle.PAPER_INITIAL)
    assert abs(run["energy"][0] - energy) <= 1e-14 * abs(energy), (run["energy"][0], energy)
    assert abs(run["entropy"][0] - entropy) <= 1e-14 * abs(entropy), (run["entropy"][0], entropy)
    np.testing.assert_array_equal(chain_state_of_pendulum_row(run["state"][0]), oracle.PAPER_INITIAL)


def test_n2_chain_moves_as_the_paper_pendulum(tmp_path, eme_run_binary):
    """relaxed_rk8 at a fixed dt = 0.01 s on the paper scene to 2 s against the N = 2 chain by DOP853
    at 1e-12: every 0.5 s the converted state agrees to 1e-9 of each quantity's largest magnitude
    (positions, momenta, gamma, temperatures). Measured: 1.3e-11 (at tolerance 1e-12 instead of a
    fixed step, relaxed_rk8's own global error is 3e-9)."""
    result, path = run_eme(tmp_path, "paper_rk8", {
        "integrator": {"scheme": "relaxed_rk8", "thermo_variable": "temperature", "dt": 0.01, "t_end": 2.0},
        "output": {"interval": 0.5}})
    assert result.returncode == 0, result.stderr
    run = read_run(path)
    with h5py.File(path) as f:
        assert f["state"].attrs["columns"].split() == PENDULUM_COLUMNS
    got = np.array([chain_state_of_pendulum_row(row) for row in run["state"]])
    expected = oracle.solve(oracle.paper_chain(), oracle.PAPER_INITIAL, run["time"])
    scales = np.concatenate([np.full(6, np.abs(expected[:, :6]).max()), np.full(6, np.abs(expected[:, 6:12]).max()),
                             np.full(2, np.abs(expected[:, 12:14]).max()), np.full(2, np.abs(expected[:, 14:]).max())])
    error = np.max(np.abs(got - expected) / scales)
    assert error < 1e-9, error
    assert run["time"][-1] == pytest.approx(2.0)


# ---------------------------------------------------------------- exact linear modes
def uniform_chain(n, law):
    """A 1D 'fixed-fixed' chain of n masses at 5 % stretch, its springs of one of three parameter sets."""
    spring = {"elastic": oracle.Spring(natural_length=0.5, mu_eq_const=80.0, heat_capacity=3.0),
              "thermoelastic": oracle.Spring(natural_length=0.5, mu_eq_const=80.0, mu_eq_slope=0.1, beta=0.8,
                                             heat_capacity=3.0),
              "thermoviscoelastic": oracle.Spring(natural_length=0.5, mu_eq_const=80.0, mu_eq_slope=0.1, beta=0.8,
                                                  heat_capacity=3.0, beta_v=0.4, mu_neq_const=30.0,
                                                  mu_neq_slope=0.02, viscosity_const=2.0,
                                                  viscosity_activation=10.0)}[law]
    return oracle.Chain(masses=np.full(n, 0.3), springs=[spring] * (n + 1), conductivity=np.full(n, 2.5),
                        gravity=[0.0], ends="fixed-fixed", span=(n + 1) * 0.5 * 1.05)


def nonlinear_jacobian(chain, y, step=1e-6):
    """The oracle field's Jacobian at y by central differences (relative steps)."""
    f = oracle.rhs(chain)
    columns = []
    for j in range(len(y)):
        h = step * max(1.0, abs(y[j]))
        plus, minus = y.copy(), y.copy()
        plus[j] += h
        minus[j] -= h
        columns.append((f(0, plus) - f(0, minus)) / (2 * h))
    return np.array(columns).T


@pytest.mark.parametrize("law", ["elastic", "thermoelastic", "thermoviscoelastic"])
def test_the_nodal_linearisation_is_the_fields_jacobian(law):
    """Section 10's linearised equations (nodal form) equal the Jacobian of the oracle's nonlinear
    field at the uniform stretch (N = 4) to 1e-6 of its largest entry, and the base state is an
    equilibrium of the field."""
    chain = uniform_chain(4, law)
    coefficients = oracle.linear_coefficients(chain, 310.0)
    _, _, y_star = oracle.base_state(chain, 310.0)
    assert np.max(np.abs(oracle.rhs(chain)(0, y_star))) < 1e-11
    expected = nonlinear_jacobian(chain, y_star)
    got = oracle.linear_system(coefficients, chain.n)
    assert np.max(np.abs(got - expected)) < 1e-6 * np.max(np.abs(expected)), np.max(np.abs(got - expected))


@pytest.mark.parametrize("law", ["elastic", "thermoelastic", "thermoviscoelastic"])
@pytest.mark.parametrize("n", [1, 3, 8])
def test_the_closed_form_mode_map_is_the_midpoint_rule_of_the_linearised_system(law, n):
    """For every mode k (0..n), ten midpoint steps of the whole nodal linear system, solved directly,
    from a state of mode k alone stay in mode k (other modes below 1e-12 of it) and equal ten Cayley
    steps of A_k to 1e-12 relative, at a dt where the thermal mode is stiff (dt |lambda_max| > 10)."""
    chain = uniform_chain(n, law)
    c = oracle.linear_coefficients(chain, 310.0)
    a = oracle.linear_system(c, n)
    dt = 20.0 / np.max(np.abs(np.linalg.eigvals(a)))
    dt = max(dt, 0.05)
    eye = np.eye(len(a))
    rng = np.random.default_rng(n)
    for k in range(n + 1):
        amplitudes = rng.uniform(-1.0, 1.0, 2 if k == 0 else 4)
        state = oracle.mode_state(n, k, amplitudes)
        modal = amplitudes.copy()
        step = oracle.cayley(oracle.mode_generator(c, n, k), dt)
        for _ in range(10):
            state = np.linalg.solve(eye - dt / 2 * a, (eye + dt / 2 * a) @ state)
            modal = step @ modal
        got = oracle.modal_amplitudes(n, state, k)
        assert np.allclose(got, modal, rtol=1e-12, atol=1e-12 * np.abs(modal).max()), (k, got, modal)
        rebuilt = oracle.mode_state(n, k, got)
        assert np.max(np.abs(state - rebuilt)) <= 1e-12 * np.max(np.abs(state)), k
    assert np.max(np.abs(np.linalg.eigvals(oracle.cayley(a, dt)))) <= 1 + 1e-12


def test_the_elastic_mode_map_in_closed_form():
    """The elastic rung's 2 x 2 map, 1/(1 + dt^2 w^2/4) [[c, dt/m], [-dt m w^2, c]], is the Cayley
    transform of its A_k, with w^2 = 4 sigma_k^2 psi_ll/m, and turns by 2 arctan(w dt/2) a step."""
    n = 5
    c = oracle.linear_coefficients(uniform_chain(n, "elastic"), 300.0)
    for k in range(1, n + 1):
        sigma = np.sin(k * np.pi / (2 * (n + 1)))
        omega = np.sqrt(4 * sigma**2 * c["ll"] / c["m"])
        for dt in (0.01, 0.3, 5.0):
            expected = oracle.cayley(oracle.mode_generator(c, n, k)[:2, :2], dt)
            got = oracle.elastic_cayley(omega, c["m"], dt)
            np.testing.assert_allclose(got, expected, rtol=1e-13, atol=1e-15)
            angle = np.angle(np.linalg.eigvals(got)).max()
            assert angle == pytest.approx(2 * np.arctan(omega * dt / 2), rel=1e-12)


# ---------------------------------------------------------------- the end state of an isolated chain
def test_a_long_run_of_an_isolated_chain_ends_in_the_predicted_end_state():
    """A 1D 'fixed-fixed' chain of 3 masses, identical thermoviscoelastic springs, started moving,
    unevenly stretched and at unlike temperatures, over 200 s (Radau at 1e-10): E stays, S rises on
    every row toward the predicted S*, and the end state is at rest with equal springs, one
    temperature theta* (E = ns u(l*, theta*, gamma*)) and relaxed dampers, to 1e-9 (measured:
    5e-12 at 200 s, 1e-13 at 400 s)."""
    chain = replace(uniform_chain(3, "thermoviscoelastic"), span=4 * 0.5 * 1.05)
    x = np.array([[0.5], [1.1], [1.5]])
    y0 = oracle.join(x, [[0.4], [-0.2], [0.3]], [0.01, -0.02, 0.0, 0.02], [280.0, 320.0, 300.0, 340.0])
    energy0, entropy0 = oracle.energy_entropy(chain, y0)
    y_star, theta_star, entropy_star = oracle.end_state(chain, energy0)
    times = np.linspace(0.0, 200.0, 21)
    states = oracle.solve(chain, y0, times, method="Radau", rtol=1e-10, atol=1e-10)
    energy, entropy = np.array([oracle.energy_entropy(chain, y) for y in states]).T
    assert np.ptp(energy) < 1e-8 * abs(energy0)
    assert np.all(np.diff(entropy) > -1e-12) and entropy[-1] > entropy0
    assert abs(entropy[-1] - entropy_star) < 1e-9 * abs(entropy_star - entropy0), (entropy[-1], entropy_star)
    scale = np.maximum(np.abs(y_star), 1e-3)
    assert np.max(np.abs(states[-1] - y_star) / scale) < 1e-9, np.max(np.abs(states[-1] - y_star) / scale)
    assert 280.0 < theta_star < 340.0


# ---------------------------------------------------------------- the continuum family
ROD = oracle.Rod(length=2.0, mass_per_length=0.8, axial_stiffness=400.0, stiffness_slope=0.2, thermal_stress=0.5,
                 heat_capacity=30.0, beta_v=0.3, maxwell_stiffness=100.0, maxwell_slope=0.1, viscosity=5.0,
                 viscosity_activation=10.0, conductivity=4.0, theta_ref=300.0)


@pytest.mark.parametrize("n_springs", [4, 16, 64])
@pytest.mark.parametrize("ends", ["fixed-free", "fixed-fixed"])
def test_the_continuum_familys_springs_are_the_rods_elements(n_springs, ends):
    """The lumped masses and the supports' halves add up to rho L; the capacities to (1 + beta_v) c L;
    a uniform 1 % stretch stores (1 + beta_v)((EA + theta_ref stiffness_slope)/2 ln(1.01)^2 + E A alpha
    theta_ref ln(1.01)) L at theta_ref (u = e of section 3), whatever N; the linear stiffness is
    EA/h, the link conductance kA/h, and the Maxwell relaxation rate 2 E^neq A/(eta A) is the same
    for every N."""
    chain = oracle.rod_chain(ROD, n_springs, ends, [0.0])
    h = ROD.length / n_springs
    supported = h / 2 * (1 if ends == "fixed-free" else 2)
    assert chain.masses.sum() + ROD.mass_per_length * supported == pytest.approx(ROD.mass_per_length * ROD.length, rel=1e-14)
    k = oracle.spring_arrays(chain)
    assert oracle.capacity(k).sum() == pytest.approx((1 + ROD.beta_v) * ROD.heat_capacity * ROD.length, rel=1e-13)
    l = np.full(chain.ns, 1.01 * h)
    _, u = oracle.entropy_energy(k, l, np.full(chain.ns, ROD.theta_ref), np.zeros(chain.ns))
    stored = u.sum()
    expected = (1 + ROD.beta_v) * ((ROD.axial_stiffness + ROD.theta_ref * ROD.stiffness_slope) / 2 * np.log(1.01)**2
                                   + ROD.thermal_stress * ROD.theta_ref * np.log(1.01)) * ROD.length
    assert stored == pytest.approx(expected, rel=1e-12)
    assert k["mu_eq_const"][0] / h**2 == pytest.approx(ROD.axial_stiffness / h, rel=1e-14)
    assert chain.conductivity[0] == pytest.approx(ROD.conductivity / h, rel=1e-14)
    assert 2 * k["mu_neq_const"][0] / k["viscosity_const"][0] == pytest.approx(2 * ROD.maxwell_stiffness / ROD.viscosity)


def test_the_continuum_familys_heat_modes_tend_to_the_rods_and_its_stiffest_grows_like_n_squared():
    """Heat conduction alone (no coupling) along a 'fixed-fixed' rod of n_s springs: the slowest decay
    rate of the adiabatic Laplacian, kappa 4 sin^2(pi/(2 n_s))/Cap, tends to the rod's (pi/L)^2 kA/(c
    (1 + beta_v)) (error below 1 % at n_s = 16, falling like 1/N^2), and the fastest, 4 kappa/Cap,
    grows like N^2: an explicit step must shrink like 1/N^2."""
    rod = replace(ROD, thermal_stress=0.0, stiffness_slope=0.0, maxwell_stiffness=0.0, beta_v=0.0)
    continuum = (np.pi / rod.length)**2 * rod.conductivity / rod.heat_capacity
    fastest, errors = [], []
    for n_springs in (16, 32, 64):
        chain = oracle.rod_chain(rod, n_springs, "fixed-fixed", [0.0])
        c = oracle.linear_coefficients(chain, rod.theta_ref)
        rates = [-oracle.mode_generator(c, chain.n, k)[3, 3] for k in range(1, chain.n + 1)]
        errors.append(abs(min(rates) - continuum) / continuum)
        fastest.append(max(rates))
    assert errors[0] < 1e-2 and errors[1] < errors[0] / 3.5 and errors[2] < errors[1] / 3.5, errors
    ratios = np.array(fastest[1:]) / np.array(fastest[:-1])
    assert np.all(np.abs(ratios - 4.0) < 0.05), ratios
