"""An independent numpy implementation of the thermoviscoelastic double pendulum's continuous
evolution equations, used as a reference for the project's integrators on a short interval.

What this establishes: on a scene that breaks every symmetry of the paper's (unequal masses and
springs, other Table 1 values, gravity off the z axis, a non-mirror-symmetric initial state with
gamma != 0), eme_run's final q, p, gamma and temperatures agree with an RK4 solution of the
equations typed here from the paper (eqs. (1), (6), (12), (16), (17)) and docs/formulation.md section 4:
to 1e-10 for the adaptive ts_rk5dp baseline (ts_tolerance 1e-12), and to a few times the
measured O(dt^2) error for EME (dt = 0.001) in each thermodynamic variable; and E, S at t = 0 agree with the project's /energy, /entropy to round-off.

What it is independent of: nothing under src/ (the Fortran model) or tests/unit/ was read to
write it. The free energies are coded as the paper writes (16)-(17), not in docs/formulation.md
section 3's closed forms; their derivatives are written by hand from (16)-(17) and checked
against complex-step differentiation below. The only project code used is tests/conftest.py
(to write the namelist and run the driver) and the documented HDF5 layout (docs/output.md).

The reference verifies itself before it judges the code: its energy E = T + V_g + U_1 + U_2 is
conserved to 1e-10 relative (measured ~4e-14) and its entropy S never decreases; halving its step changes the end state
far below the tolerances. A last test shows that plausible bugs (conductivity doubled, gravity
reversed, masses swapped, viscosity / 10, heat capacities swapped, mu_neq_slope sign flipped)
move the reference by more than 10 times the loosest tolerance.
"""
from dataclasses import dataclass, replace

import h5py
import numpy as np
import pytest

from conftest import read_run, run_eme

# ---------------------------------------------------------------------------------------------
# The scene: differs from the paper's everywhere the paper is symmetric (Table 1, section 4).
# ---------------------------------------------------------------------------------------------
MODEL = {
    "mass": [1.0, 2.5],
    "natural_length": [1.2, 1.8],
    "mu_eq_const": [150.0, 250.0],
    "mu_eq_slope": [0.3, 0.7],
    "mu_neq_const": 8.0,
    "mu_neq_slope": 0.05,
    "heat_capacity": [12.0, 7.0],
    "viscosity_const": 40.0,
    "viscosity_activation": 25.0,
    "conductivity": 2.0,
    "theta_ref": 295.0,
    "beta": 0.05,
    "beta_v": 0.3,
    "gravity": [1.2, -9.7, 0.4],
}
INITIAL = {
    "q1": [0.9, 0.3, -0.4],
    "q2": [1.6, -0.5, 0.7],
    "p1": [0.4, -0.2, 0.3],
    "p2": [-1.0, 0.6, 0.5],
    "gamma": 0.05,
    "theta": [290.0, 330.0],
}
T_END = 0.5
RK4_STEP = 2.5e-4          # reference step; its error is checked by halving it (test below)

# Tolerances on the end state, as (mechanical, thermal) relative errors (see relative_errors).
# Measured on this scene: ts_rk5dp at ts_tolerance 1e-12: 4.9e-13, 9.1e-15 (the reference's own
# error is 1.7e-13, 8e-15), so 1e-10 leaves a margin of 200. EME at dt = 0.001, every variable:
# 2.60e-6, 1.09e-7 (2.60e-6 -> 1.04e-5 at dt = 0.002: second order), so a factor of about 4.
TOL_TS = (1e-10, 1e-10)
TOL_EME = (1e-5, 4e-7)
TOL_STATE_FUNCTIONS = 1e-12   # E and S at t = 0, relative


@dataclass(frozen=True)
class Params:
    """The &model group as plain numbers (docs/input.md; Table 1 names in comments)."""
    m1: float
    m2: float                 # m_alpha
    l0: tuple                 # lambda_alpha^0
    mu_c: tuple               # mu^eq_{alpha,cst}
    mu_t: tuple               # mu^eq_{alpha,theta}
    mun_c: float              # mu^neq_{2,cst}
    mun_t: float              # mu^neq_{2,theta}
    c: tuple                  # c_alpha^0
    eta_c: float              # eta_cst
    eta_t: float              # eta_theta
    kappa: float              # k
    theta_ref: float
    beta: float
    beta_v: float
    g: tuple


def params_from(model):
    """Params from a &model dict with the field names of docs/input.md."""
    return Params(
        m1=model["mass"][0], m2=model["mass"][1], l0=tuple(model["natural_length"]),
        mu_c=tuple(model["mu_eq_const"]), mu_t=tuple(model["mu_eq_slope"]),
        mun_c=model["mu_neq_const"], mun_t=model["mu_neq_slope"],
        c=tuple(model["heat_capacity"]), eta_c=model["viscosity_const"],
        eta_t=model["viscosity_activation"], kappa=model["conductivity"],
        theta_ref=model["theta_ref"], beta=model["beta"], beta_v=model["beta_v"],
        g=tuple(model["gravity"]))


P = params_from(MODEL)

# ---------------------------------------------------------------------------------------------
# Free energies, eqs. (16)-(17), exactly as the paper writes them, and their derivatives.
# ---------------------------------------------------------------------------------------------


def mu_eq(P, a, theta):
    """mu_alpha^eq(theta) = mu_cst - mu_theta (theta - theta_ref), eq. (17)."""
    return P.mu_c[a] - P.mu_t[a] * (theta - P.theta_ref)


def mu_neq(P, theta):
    """mu_2^neq(theta) = mu^neq_cst - mu^neq_theta (theta - theta_ref), eq. (17)."""
    return P.mun_c - P.mun_t * (theta - P.theta_ref)


def eta(P, theta):
    """eta(theta) = eta_cst exp[eta_theta (1/theta - 1/theta_ref)], eq. (17)."""
    return P.eta_c * np.exp(P.eta_t * (1.0 / theta - 1.0 / P.theta_ref))


def psi_eq(P, a, l, theta):
    """psi_alpha^eq(l, theta), eq. (16): mu/2 ln^2(l/l0) - beta (theta - theta_ref) ln(l/l0)
    + c (theta - theta_ref - theta ln(theta/theta_ref))."""
    L = np.log(l / P.l0[a])
    return (mu_eq(P, a, theta) / 2 * L**2 - P.beta * (theta - P.theta_ref) * L
            + P.c[a] * (theta - P.theta_ref - theta * np.log(theta / P.theta_ref)))


def dpsi_eq_dl(P, a, l, theta):
    """d psi_alpha^eq / d l = (mu L - beta (theta - theta_ref)) / l (by hand from (16))."""
    L = np.log(l / P.l0[a])
    return (mu_eq(P, a, theta) * L - P.beta * (theta - P.theta_ref)) / l


def psi1(P, l, theta):
    """psi_1(l_1, theta_1) = psi_1^eq, eq. (16) (spring 1 is thermoelastic)."""
    return psi_eq(P, 0, l, theta)


def psi2(P, l, theta, gamma):
    """psi_2 = psi_2^eq + psi_2^neq with psi_2^neq = beta_v psi_2^eq + mu^neq gamma^2
    - beta_v gamma d psi_2^eq/d l, eq. (16)."""
    return ((1 + P.beta_v) * psi_eq(P, 1, l, theta) + mu_neq(P, theta) * gamma**2
            - P.beta_v * gamma * dpsi_eq_dl(P, 1, l, theta))


def spring_derivatives(P, l1, l2, th1, th2, gamma):
    """First and mixed derivatives of psi_1, psi_2 written by hand from (16)-(17).

    Returns dict with: f1 = d psi_1/d l, f2 = d psi_2/d l, fg = d psi_2/d gamma, the entropies
    s_a = -d psi_a/d theta, and ds_a/d l, ds_2/d gamma, ds_a/d theta (all at fixed others).
    psi is affine in theta except the c-term, so these are short and exact; they are checked
    against complex-step derivatives of psi1/psi2 in test_hand_derivatives_match_complex_step."""
    out = {}
    for a, l, th in ((0, l1, th1), (1, l2, th2)):
        L = np.log(l / P.l0[a])
        mu, mut = mu_eq(P, a, th), P.mu_t[a]
        f = (mu * L - P.beta * (th - P.theta_ref)) / l                  # d psi^eq/d l
        f_l = (mu - mu * L + P.beta * (th - P.theta_ref)) / l**2         # d2 psi^eq/d l2
        f_t = (-mut * L - P.beta) / l                                    # d2 psi^eq/d l d theta
        f_lt = (-mut + mut * L + P.beta) / l**2                          # d3 psi^eq/d l2 d theta
        psi_t = -mut / 2 * L**2 - P.beta * L - P.c[a] * np.log(th / P.theta_ref)
        out[a] = dict(L=L, f=f, f_l=f_l, f_t=f_t, f_lt=f_lt, psi_t=psi_t)
    e1, e2 = out[0], out[1]
    bv = P.beta_v
    return {
        "f1": e1["f"],
        "f2": (1 + bv) * e2["f"] - bv * gamma * e2["f_l"],
        "fg": 2 * mu_neq(P, th2) * gamma - bv * e2["f"],
        "s1": -e1["psi_t"],
        "s2": -((1 + bv) * e2["psi_t"] - P.mun_t * gamma**2 - bv * gamma * e2["f_t"]),
        "s1_l": -e1["f_t"],
        "s2_l": -((1 + bv) * e2["f_t"] - bv * gamma * e2["f_lt"]),
        "s2_g": 2 * P.mun_t * gamma + bv * e2["f_t"],
        "s1_t": P.c[0] / th1,
        "s2_t": (1 + bv) * P.c[1] / th2,
    }


# ---------------------------------------------------------------------------------------------
# Mechanics, eq. (1) and section 2 of docs/formulation.md; the state is y = (q1, q2, p1, p2, gamma,
# theta1, theta2) (temperature as thermodynamic variable, same column order as /state).
# ---------------------------------------------------------------------------------------------


def mass_matrix(P):
    """m = [[(m1+m2) I, m2 I], [m2 I, m2 I]], eq. (1) (6x6, acting on (q1, q2))."""
    eye = np.eye(3)
    return np.block([[(P.m1 + P.m2) * eye, P.m2 * eye], [P.m2 * eye, P.m2 * eye]])


def split(y):
    return y[0:3], y[3:6], y[6:9], y[9:12], y[12], y[13], y[14]


def rhs(P, y, minv):
    """Continuous evolution equations in the temperature variable.

    - qdot = m^-1 p (eq. (1), p = m qdot).
    - pdot_a = -grad_{q_a} V_g - (d psi_a/d l_a) q_a/l_a at constant theta: docs/formulation.md section 4's
      -(grad_qa E - Theta_a grad_qa S_a) with tau = theta is -grad_qa (U_a - theta S_a) =
      -grad_qa psi_a, plus gravity V_g = -(m1+m2) g.q1 - m2 g.q2 (docs/formulation.md section 2).
    - gammadot = -(1/eta(theta_2)) d psi_2/d gamma: K0's gamma entry theta_2/eta (eq. (12))
      times y = -d_gamma psi_2/theta_2 (docs/formulation.md section 4).
    - entropy balance (tau = s rows of K = M_E K0 M_E^T, eq. (12); the reversible tau = s rows
      vanish, docs/formulation.md section 4): ds_1/dt = kappa (theta_2 - theta_1)/theta_1 and
      ds_2/dt = kappa (theta_1 - theta_2)/theta_2 + eta gammadot^2/theta_2, where the last term
      is docs/formulation.md section 4's -(d_gamma U_2/d_s U_2) gammadot with d_gamma U_2|_s = d_gamma psi_2|_theta
      = -eta gammadot and d_s U_2 = theta_2 (viscous dissipation, >= 0).
    - thetadot_a from ds_a/dt = s_a,l ldot_a + s_a,gamma gammadot + s_a,theta thetadot_a, which
      reproduces docs/formulation.md section 4's tau = theta rows (d_theta S = Cap/theta, d_theta U = Cap).
    """
    q1, q2, p1, p2, gamma, th1, th2 = split(y)
    qdot = minv @ y[6:12]
    l1, l2 = np.sqrt(q1 @ q1), np.sqrt(q2 @ q2)
    d = spring_derivatives(P, l1, l2, th1, th2, gamma)
    g = np.asarray(P.g)
    p1dot = (P.m1 + P.m2) * g - d["f1"] * q1 / l1
    p2dot = P.m2 * g - d["f2"] * q2 / l2
    et = eta(P, th2)
    gdot = -d["fg"] / et
    s1dot = P.kappa * (th2 - th1) / th1
    s2dot = P.kappa * (th1 - th2) / th2 + et * gdot**2 / th2
    l1dot = q1 @ qdot[0:3] / l1
    l2dot = q2 @ qdot[3:6] / l2
    th1dot = (s1dot - d["s1_l"] * l1dot) / d["s1_t"]
    th2dot = (s2dot - d["s2_l"] * l2dot - d["s2_g"] * gdot) / d["s2_t"]
    return np.concatenate([qdot, p1dot, p2dot, [gdot, th1dot, th2dot]])


def energy_entropy(P, y, minv):
    """E = T + V_g + U_1 + U_2 (eq. (6) plus gravity) and S = s_1 + s_2, with u = psi + theta s
    and s = -d psi/d theta (Legendre transformation, section 1 of the paper)."""
    q1, q2, p1, p2, gamma, th1, th2 = split(y)
    p = y[6:12]
    l1, l2 = np.sqrt(q1 @ q1), np.sqrt(q2 @ q2)
    d = spring_derivatives(P, l1, l2, th1, th2, gamma)
    g = np.asarray(P.g)
    kinetic = 0.5 * p @ minv @ p
    gravity = -(P.m1 + P.m2) * g @ q1 - P.m2 * g @ q2
    u1 = psi1(P, l1, th1) + th1 * d["s1"]
    u2 = psi2(P, l2, th2, gamma) + th2 * d["s2"]
    return kinetic + gravity + u1 + u2, d["s1"] + d["s2"]


def initial_state(initial):
    """y0 from an &initial dict (temperature variable)."""
    return np.concatenate([initial["q1"], initial["q2"], initial["p1"], initial["p2"],
                           [initial["gamma"]], initial["theta"]]).astype(float)


def rk4(P, y0, t_end, h_max, record=False):
    """Classic RK4 from 0 to t_end with n = ceil(t_end/h_max) equal steps. Returns the end state
    (and with record=True the energies and entropies at every step)."""
    minv = np.linalg.inv(mass_matrix(P))
    n = int(np.ceil(t_end / h_max - 1e-9))
    h = t_end / n
    y = y0.copy()
    history = [energy_entropy(P, y, minv)] if record else None
    for _ in range(n):
        k1 = rhs(P, y, minv)
        k2 = rhs(P, y + h / 2 * k1, minv)
        k3 = rhs(P, y + h / 2 * k2, minv)
        k4 = rhs(P, y + h * k3, minv)
        y = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        if record:
            history.append(energy_entropy(P, y, minv))
    return (y, np.array(history)) if record else y


_REFERENCE_CACHE = {}


def reference(P, t_end, h=RK4_STEP):
    """Cached reference end state for parameters P at t_end."""
    key = (P, round(t_end, 14), h)
    if key not in _REFERENCE_CACHE:
        _REFERENCE_CACHE[key] = rk4(P, initial_state(INITIAL), t_end, h)
    return _REFERENCE_CACHE[key]


def relative_errors(y, y_ref):
    """(mechanical, thermal) error: max |(q, p, gamma) - ref| / max |(q, p, gamma)_ref| and
    max |theta - theta_ref| / max |theta_ref|."""
    mech = np.abs(y[:13] - y_ref[:13]).max() / np.abs(y_ref[:13]).max()
    therm = np.abs(y[13:] - y_ref[13:]).max() / np.abs(y_ref[13:]).max()
    return mech, therm


# ---------------------------------------------------------------------------------------------
# Running the project
# ---------------------------------------------------------------------------------------------


def _text(value):
    return value.decode() if isinstance(value, bytes) else str(value)


def run_project(tmp_path, name, integrator, model=None):
    """Runs eme_run on the scene (or with `model`'s &model instead); returns (t_end, end state in
    the temperature variable, run)."""
    result, path = run_eme(tmp_path, name, {"model": model or MODEL, "initial": INITIAL,
                                            "integrator": integrator})
    assert result.returncode == 0, f"eme_run {integrator} failed:\n{result.stdout}\n{result.stderr}"
    data = read_run(path)
    assert data["attrs"]["status"] == "complete", data["attrs"]["status"]
    with h5py.File(path, "r") as f:
        state_cols = _text(f["state"].attrs["columns"]).split()
        temp_cols = _text(f["temperature"].attrs["columns"]).split()
    state = dict(zip(state_cols, data["state"][-1]))
    temps = dict(zip(temp_cols, data["temperature"][-1]))
    names = [f"{v}_{c}" for v in ("q1", "q2", "p1", "p2") for c in "xyz"] + ["gamma"]
    y = np.array([state[n] for n in names] + [temps["theta_1"], temps["theta_2"]])
    return float(data["time"][-1]), y, data


# ---------------------------------------------------------------------------------------------
# Tests
# ---------------------------------------------------------------------------------------------


def complex_step(f, x, h=1e-30):
    """df/dx = Im f(x + i h)/h, exact to round-off (no subtractive cancellation)."""
    return np.imag(f(x + 1j * h)) / h


def test_hand_derivatives_match_complex_step():
    """The hand-written derivatives of (16)-(17) against complex-step derivatives of psi as the
    paper writes it (first derivatives exact to round-off; the second derivatives by central
    differences, step 1e-4 relative, of complex-step first derivatives: truncation ~1e-8 and
    round-off ~1e-12, so they are checked to 1e-6 relative)."""
    l1, l2, th1, th2, gamma = 1.37, 1.93, 287.0, 336.0, 0.08
    d = spring_derivatives(P, l1, l2, th1, th2, gamma)
    exact = {
        "f1": complex_step(lambda l: psi1(P, l, th1), l1),
        "f2": complex_step(lambda l: psi2(P, l, th2, gamma), l2),
        "fg": complex_step(lambda g: psi2(P, l2, th2, g), gamma),
        "s1": -complex_step(lambda t: psi1(P, l1, t), th1),
        "s2": -complex_step(lambda t: psi2(P, l2, t, gamma), th2),
    }
    for key, value in exact.items():
        assert abs(d[key] - value) <= 1e-13 * max(1.0, abs(value)), \
            f"{key}: hand {d[key]!r} vs complex step {value!r}, tolerance 1e-13 relative"

    def central(f, x, rel=1e-4):
        h = rel * max(abs(x), 1.0)
        return (f(x + h) - f(x - h)) / (2 * h)

    s1 = lambda l, t: -complex_step(lambda tt: psi1(P, l, tt), t)
    s2 = lambda l, t, g: -complex_step(lambda tt: psi2(P, l, tt, g), t)
    second = {
        "s1_l": central(lambda l: s1(l, th1), l1),
        "s1_t": central(lambda t: s1(l1, t), th1),
        "s2_l": central(lambda l: s2(l, th2, gamma), l2),
        "s2_g": central(lambda g: s2(l2, th2, g), gamma),
        "s2_t": central(lambda t: s2(l2, t, gamma), th2),
    }
    for key, value in second.items():
        assert abs(d[key] - value) <= 1e-6 * max(1e-3, abs(value)), \
            f"{key}: hand {d[key]!r} vs differenced complex step {value!r}, tolerance 1e-6 relative"


def test_reference_conserves_energy_and_produces_entropy():
    """Self-check of the reference before it judges the code (paper section 2: dE/dt = 0 and
    dS/dt >= 0 for the closed system): along the RK4 solution E = T + V_g + U_1 + U_2 stays
    constant to 1e-10 relative and S never decreases from one step to the next."""
    _, history = rk4(P, initial_state(INITIAL), T_END, RK4_STEP, record=True)
    energy, entropy = history[:, 0], history[:, 1]
    drift = np.abs(energy - energy[0]).max() / abs(energy[0])
    assert drift < 1e-10, f"reference energy drift max|E - E0|/|E0| = {drift:.3e}, tolerance 1e-10"
    steps = np.diff(entropy)
    assert steps.min() >= 0.0, \
        f"reference entropy decreases: min S_(n+1) - S_n = {steps.min():.3e} J/K, must be >= 0"
    assert entropy[-1] - entropy[0] > 0.0, "no entropy produced: the dissipation is missing"


def test_reference_step_is_converged():
    """Halving the RK4 step changes the reference's end state by far less than the tightest
    tolerance (1/100 of TOL_TS), so the comparisons below measure the project's error only."""
    y0 = initial_state(INITIAL)
    coarse, fine = reference(P, T_END), rk4(P, y0, T_END, RK4_STEP / 2)
    errors = relative_errors(coarse, fine)
    for what, err, tol in zip(("mechanical", "thermal"), errors, TOL_TS):
        assert err < tol / 100, \
            f"reference h = {RK4_STEP} vs h/2, {what} relative difference {err:.3e}, " \
            f"tolerance {tol / 100:.1e}"


CASES = {
    "ts_rk5dp": ({"scheme": "ts_rk5dp", "thermo_variable": "temperature", "dt": 0.05,
                  "t_end": T_END, "ts_tolerance": 1e-12}, TOL_TS),
    **{f"eme_{v}": ({"scheme": "eme", "thermo_variable": v, "dt": 0.001, "t_end": T_END}, TOL_EME)
       for v in ("entropy", "temperature", "internal_energy")},
}


@pytest.mark.parametrize("case", list(CASES))
def test_project_matches_independent_reference(tmp_path, eme_run_binary, case):
    """The project's end state (q, p, gamma from /state, theta from /temperature, at the last
    /time) against the RK4 reference at the same time; and /energy, /entropy at t = 0 against
    E and S of the initial state (state functions: equal to round-off)."""
    integrator, tolerances = CASES[case]
    t_end, y, data = run_project(tmp_path, case, integrator)
    assert abs(t_end - T_END) < 1e-9, f"{case}: last /time {t_end!r}, expected {T_END}"
    y_ref = reference(P, t_end)
    for what, err, tol in zip(("mechanical (q, p, gamma)", "thermal (theta_1, theta_2)"),
                              relative_errors(y, y_ref), tolerances):
        assert err <= tol, (
            f"{case}: {what} relative error at t = {t_end} is {err:.3e}, tolerance {tol:.1e}; "
            f"project {np.array2string(y, precision=10)}, "
            f"reference {np.array2string(y_ref, precision=10)}")

    minv = np.linalg.inv(mass_matrix(P))
    energy, entropy = energy_entropy(P, initial_state(INITIAL), minv)
    for what, theirs, ours in (("/energy[0] vs E", data["energy"][0], energy),
                               ("/entropy[0] vs S", data["entropy"][0], entropy)):
        rel = abs(theirs - ours) / abs(ours)
        assert rel <= TOL_STATE_FUNCTIONS, (
            f"{case}: {what} at t = 0: project {theirs!r}, reference {ours!r}, relative "
            f"difference {rel:.3e}, tolerance {TOL_STATE_FUNCTIONS:.0e}")


def test_a_stiffness_independent_of_temperature(tmp_path, eme_run_binary):
    """mu_eq_slope = 0 (a stiffness that does not depend on temperature, as the thermoelastic
    pendulum of Romero's dataset has) is accepted, and the project follows the reference with it:
    ts_rk5dp at tolerance 1e-12 to 1e-9, EME to its O(dt^2) error; the reference itself moves by
    far more than that from the scene with slopes (the test sees the slope)."""
    model = dict(MODEL, mu_eq_slope=[0.0, 0.0])
    P0 = params_from(model)
    y_ref = reference(P0, T_END)
    assert np.abs(y_ref - reference(P, T_END)).max() > 1e-6
    t_end, y, _ = run_project(tmp_path, "slope0_rk5dp", {"scheme": "ts_rk5dp", "dt": 0.01, "t_end": T_END,
                                                       "tolerance": 1e-12}, model)
    assert max(relative_errors(y, y_ref)) < 1e-9
    t_end, y, data = run_project(tmp_path, "slope0_eme", {"scheme": "eme", "dt": 0.001, "t_end": T_END,
                                                        "newton_tol": 1e-12}, model)
    assert max(relative_errors(y, y_ref)) < 1e-5
    assert np.abs(data["energy"] - data["energy"][0]).max() < 1e-12 * abs(data["energy"][0])


PERTURBATIONS = {
    "conductivity doubled": lambda P: replace(P, kappa=2 * P.kappa),
    "gravity reversed": lambda P: replace(P, g=tuple(-x for x in P.g)),
    "masses swapped": lambda P: replace(P, m1=P.m2, m2=P.m1),
    "viscosity_const / 10": lambda P: replace(P, eta_c=P.eta_c / 10),
    "heat capacities swapped": lambda P: replace(P, c=P.c[::-1]),
    "mu_neq_slope sign flipped": lambda P: replace(P, mun_t=-P.mun_t),
}


@pytest.mark.parametrize("bug", list(PERTURBATIONS))
def test_comparison_can_see_these_bugs(bug):
    """The comparison can see these bugs: a reference with a deliberately wrong parameter ends
    (at T_END) more than 10 times the loosest tolerance (EME's) away from the correct one in at
    least one of the two error measures."""
    wrong = reference(PERTURBATIONS[bug](P), T_END)
    errors = relative_errors(wrong, reference(P, T_END))
    ratios = [err / tol for err, tol in zip(errors, TOL_EME)]
    assert max(ratios) > 10, (
        f"{bug}: perturbed vs correct reference, relative differences (mechanical, thermal) = "
        f"({errors[0]:.3e}, {errors[1]:.3e}), tolerances {TOL_EME}, ratios "
        f"({ratios[0]:.1f}, {ratios[1]:.1f}); need > 10 in one of them")
