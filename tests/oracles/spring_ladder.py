"""The lower rungs of the spring ladder (issue 32), typed from the definitions for the tests (not
from src/): docs/formulation.md sections 2 to 4 with the viscous branch removed, and the
elastic double spring pendulum of Gonzalez's energy-momentum papers.

State (docs/formulation.md section 2), in `dim` = 2 or 3 components per vector:

    q1 = x1 (mass 1 from the suspension point),   q2 = x2 - x1 (mass 2 relative to mass 1),
    p1 = m1 v1 + m2 v2,                            p2 = m2 v2,

the momenta conjugate to (q1, q2) under T = 1/2 m1 |v1|^2 + 1/2 m2 |v2|^2 with v1 = dq1/dt,
v2 = dq1/dt + dq2/dt; inverted, v1 = (p1 - p2)/m1, v2 = p2/m2, so

    dq1/dt = (p1 - p2)/m1,     dq2/dt = p2/m2 - (p1 - p2)/m1.

Gravity g (a vector of `dim` components) acts on both masses in absolute positions,
V_g = -m1 g.x1 - m2 g.x2 = -(m1 + m2) g.q1 - m2 g.q2.

Spring a has length l_a = |q_a| and logarithmic strain L_a = ln(l_a/l0_a).

(a) Elastic: W_a = mu_a/2 L_a^2 (the free energy of section 3 at theta = theta_ref without its
    beta and thermal terms), so the force on q_a is -dW_a/dl_a q_a/l_a = -mu_a L_a q_a/l_a^2 and

        dp1/dt = (m1 + m2) g - mu_1 L_1 q1/l1^2,     dp2/dt = m2 g - mu_2 L_2 q2/l2^2,

    E = T + V_g + W_1 + W_2.

(b) Thermoelastic: psi_a(l, theta) = mu_a(theta)/2 L_a^2 - beta (theta - theta_ref) L_a
    + c_a (theta - theta_ref - theta ln(theta/theta_ref)) with mu_a(theta) = mu_const_a
    - mu_slope_a (theta - theta_ref) (eqs. (16)-(17) with beta_v = 0), so
    s_a = -d_theta psi_a = mu_slope_a/2 L_a^2 + beta L_a + c_a ln(theta_a/theta_ref) and
    u_a = psi_a + theta s_a = (mu_const_a + mu_slope_a theta_ref)/2 L_a^2 + beta theta_ref L_a
    + c_a (theta_a - theta_ref). The springs exchange heat by Fourier's law with conductivity
    kappa, the only dissipation: theta_a ds_a/dt = kappa (theta_b - theta_a). In the temperatures,

        dp_a/dt   = (gravity) - d_l psi_a(l_a, theta_a) q_a/l_a,
                    d_l psi_a = (mu_a(theta_a) L_a - beta (theta_a - theta_ref))/l_a,
        c_a dtheta_a/dt = -theta_a (mu_slope_a L_a + beta) dL_a/dt + kappa (theta_b - theta_a),
                    dL_a/dt = q_a.(dq_a/dt)/l_a^2,

    E = T + V_g + u_1 + u_2 is conserved, S = s_1 + s_2 rises at
    kappa (theta_1 - theta_2)^2/(theta_1 theta_2), and J = q1 x p1 + q2 x p2 (a scalar in 2D)
    is kept when gravity vanishes (its component along g when it does not, in 3D).

The reference solution is SciPy's DOP853 (or Radau) at rtol = atol = 1e-12 unless told.
"""
from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import solve_ivp


@dataclass
class Springs:
    """Parameters of a double spring pendulum in SI units (dim = len(gravity))."""
    mass: tuple
    natural_length: tuple
    mu_eq_const: tuple
    gravity: tuple
    mu_eq_slope: tuple = (0.0, 0.0)
    beta: float = 0.0
    heat_capacity: tuple = (1.0, 1.0)
    theta_ref: float = 300.0
    conductivity: float = 0.0
    dim: int = field(init=False)

    def __post_init__(self):
        self.dim = len(self.gravity)
        assert self.dim in (2, 3), self.gravity


def split(p: Springs, y):
    """(q1, q2, p1, p2, rest) of a state vector."""
    d = p.dim
    y = np.asarray(y, dtype=float)
    return y[:d], y[d:2*d], y[2*d:3*d], y[3*d:4*d], y[4*d:]


def velocities(p: Springs, p1, p2):
    """dq1/dt and dq2/dt from the momenta."""
    m1, m2 = p.mass
    v1 = (p1 - p2) / m1
    v2 = p2 / m2
    return v1, v2 - v1


def strains(p: Springs, q1, q2):
    """Lengths and logarithmic strains of both springs."""
    lengths = np.array([np.linalg.norm(q1), np.linalg.norm(q2)])
    return lengths, np.log(lengths / np.asarray(p.natural_length))


def kinetic_and_gravity(p: Springs, q1, q2, p1, p2):
    v1, dq2 = velocities(p, p1, p2)
    v2 = v1 + dq2
    m1, m2 = p.mass
    g = np.asarray(p.gravity)
    return 0.5 * m1 * v1 @ v1 + 0.5 * m2 * v2 @ v2 - (m1 + m2) * g @ q1 - m2 * g @ q2


def elastic_rhs(p: Springs):
    """(a): the field in y = (q1, q2, p1, p2)."""
    m1, m2 = p.mass
    g = np.asarray(p.gravity, dtype=float)
    mu = np.asarray(p.mu_eq_const, dtype=float)

    def f(t, y):
        q1, q2, p1, p2, _ = split(p, y)
        dq1, dq2 = velocities(p, p1, p2)
        l, strain = strains(p, q1, q2)
        dp1 = (m1 + m2) * g - mu[0] * strain[0] * q1 / l[0]**2
        dp2 = m2 * g - mu[1] * strain[1] * q2 / l[1]**2
        return np.concatenate([dq1, dq2, dp1, dp2])
    return f


def elastic_energy(p: Springs, y):
    """E = T + V_g + sum_a mu_a/2 L_a^2."""
    q1, q2, p1, p2, _ = split(p, y)
    _, strain = strains(p, q1, q2)
    return kinetic_and_gravity(p, q1, q2, p1, p2) + 0.5 * np.dot(p.mu_eq_const, strain**2)


def thermoelastic_rhs(p: Springs):
    """(b): the field in y = (q1, q2, p1, p2, theta1, theta2)."""
    m1, m2 = p.mass
    g = np.asarray(p.gravity, dtype=float)
    const, slope = np.asarray(p.mu_eq_const, float), np.asarray(p.mu_eq_slope, float)
    cap = np.asarray(p.heat_capacity, float)

    def f(t, y):
        q1, q2, p1, p2, theta = split(p, y)
        dq1, dq2 = velocities(p, p1, p2)
        l, strain = strains(p, q1, q2)
        mu = const - slope * (theta - p.theta_ref)
        dpsi_dl = (mu * strain - p.beta * (theta - p.theta_ref)) / l
        dp1 = (m1 + m2) * g - dpsi_dl[0] * q1 / l[0]
        dp2 = m2 * g - dpsi_dl[1] * q2 / l[1]
        dstrain = np.array([q1 @ dq1, q2 @ dq2]) / l**2
        heat = p.conductivity * (theta[::-1] - theta)
        dtheta = (-theta * (slope * strain + p.beta) * dstrain + heat) / cap
        return np.concatenate([dq1, dq2, dp1, dp2, dtheta])
    return f


def thermoelastic_energy_entropy(p: Springs, y):
    """(E, S) = (T + V_g + u_1 + u_2, s_1 + s_2) at a state with temperatures."""
    q1, q2, p1, p2, theta = split(p, y)
    _, strain = strains(p, q1, q2)
    const, slope = np.asarray(p.mu_eq_const, float), np.asarray(p.mu_eq_slope, float)
    cap = np.asarray(p.heat_capacity, float)
    u = (0.5 * (const + slope * p.theta_ref) * strain**2 + p.beta * p.theta_ref * strain
         + cap * (theta - p.theta_ref))
    s = 0.5 * slope * strain**2 + p.beta * strain + cap * np.log(theta / p.theta_ref)
    return kinetic_and_gravity(p, q1, q2, p1, p2) + u.sum(), s.sum()


def angular_momentum(p: Springs, y):
    """J = q1 x p1 + q2 x p2: three components in 3D, the scalar q_x p_y - q_y p_x in 2D."""
    q1, q2, p1, p2, _ = split(p, y)
    if p.dim == 2:
        return q1[0]*p1[1] - q1[1]*p1[0] + q2[0]*p2[1] - q2[1]*p2[0]
    return np.cross(q1, p1) + np.cross(q2, p2)


def reference(p: Springs, y0, times, thermal, method="DOP853", rtol=1e-12, atol=1e-12):
    """The solution at `times` (rows), of the thermoelastic field when `thermal`, else the elastic."""
    f = thermoelastic_rhs(p) if thermal else elastic_rhs(p)
    times = np.atleast_1d(np.asarray(times, dtype=float))
    solution = solve_ivp(f, (0.0, times[-1]), np.asarray(y0, dtype=float), method=method, rtol=rtol, atol=atol,
                         t_eval=times, dense_output=False)
    assert solution.success, solution.message
    return solution.y.T


def state_vector(initial, dim, thermal):
    """y0 from a namelist-like &initial dict (q1, q2, p1, p2 and, when thermal, theta), cut to dim."""
    parts = [np.asarray(initial[name], dtype=float)[:dim] for name in ("q1", "q2", "p1", "p2")]
    if thermal:
        parts.append(np.asarray(initial["theta"], dtype=float))
    return np.concatenate(parts)


def from_dataset(x1, x2, P1, P2):
    """The project's (q1, q2, p1, p2) from absolute positions and the masses' own momenta, as the
    public dataset of Hernandez et al. stores them: q1 = x1, q2 = x2 - x1, p1 = P1 + P2, p2 = P2."""
    x1, x2, P1, P2 = (np.asarray(v, dtype=float) for v in (x1, x2, P1, P2))
    return x1, x2 - x1, P1 + P2, P2


# ---------------------------------------------------------------- the published scenes
# As inputs/romero_thermoelastic.nml and inputs/gonzalez_elastic.nml state them (planar, so two
# components per vector; tests/e2e/test_spring_ladder.py checks the files against these).

# Romero's thermoelastic double pendulum with the parameters fitted to the public dataset of
# Hernandez et al. (J. Comput. Phys. 2021, quercushernandez/StructurePreservingNN,
# data/database_double_pendulum.mat; dt = 0.3 s): the scene, not identified physics. The first
# snapshot of one trajectory is the initial state (tests/e2e/test_smooth_scene.py's FIRST).
ROMERO = Springs(mass=(1.0, 2.0), natural_length=(1.99986286, 0.999926771),
                 mu_eq_const=(0.0189210127, 0.188568578), gravity=(0.0, 0.0), mu_eq_slope=(0.0, 0.0),
                 beta=0.086863612, heat_capacity=(4.99137876, 4.99137876), theta_ref=299.451937,
                 conductivity=300.0)
ROMERO_INITIAL = {"q1": [4.6695264660334814, 4.7505354853332937], "q2": [-2.427088459820355, -0.054687203651120342],
                  "p1": [0.86841516403954477, 1.2001605776636948], "p2": [1.4634168524405062, -0.18753872949487485],
                  "theta": [294.0516585031142, 294.07872994307326]}

# An elastic double spring pendulum in the spirit of Gonzalez's energy-momentum examples; the
# data are this project's choice: equal masses and lengths, springs of linear stiffness
# mu/l0^2 = 100 N/m, no gravity (so that E and the scalar J are both first integrals), the upper
# spring stretched by 10 % and both masses set turning.
GONZALEZ = Springs(mass=(1.0, 1.0), natural_length=(1.0, 1.0), mu_eq_const=(100.0, 100.0), gravity=(0.0, 0.0))
GONZALEZ_INITIAL = {"q1": [1.1, 0.0], "q2": [0.0, 1.0], "p1": [0.0, 3.0], "p2": [-1.0, 1.0]}


def full_model(scene: Springs, initial, elastic=False):
    """The (&model, &initial) groups of today's spatial thermoviscoelastic model that reduce to a
    planar scene of a lower rung: z components 0, the viscous branch inert (beta_v = 0, gamma = 0),
    and for the elastic rung also beta = 0, a stiffness constant in temperature and no
    conduction, so that the temperatures stay where they start (at theta_ref: no thermal energy)."""
    def spatial(vector):
        return list(vector) + [0.0] * (3 - len(vector))
    model = {"mass": list(scene.mass), "natural_length": list(scene.natural_length),
             "mu_eq_const": list(scene.mu_eq_const), "mu_eq_slope": list(scene.mu_eq_slope),
             "beta_v": 0.0, "gravity": spatial(scene.gravity)}
    start = {name: spatial(initial[name]) for name in ("q1", "q2", "p1", "p2")}
    start["gamma"] = 0.0
    if elastic:
        model.update(beta=0.0, mu_eq_slope=[0.0, 0.0], conductivity=0.0, theta_ref=scene.theta_ref)
        start["theta"] = [scene.theta_ref, scene.theta_ref]
    else:
        model.update(beta=scene.beta, heat_capacity=list(scene.heat_capacity), theta_ref=scene.theta_ref,
                     conductivity=scene.conductivity)
        start["theta"] = list(initial["theta"])
    return model, start
