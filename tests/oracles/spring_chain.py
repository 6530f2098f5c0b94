"""The spring chain of issue 39, typed from docs/formulation.md section 10 for the tests (not from
src/): the continuous field in the temperature variable, E, S and the momenta, the continuum
family's spring values, the exact linear modes with the midpoint rule's step map per mode, and the
end state of an isolated chain.

State (section 10), in `dim` = 1, 2 or 3 components per vector, absolute positions and the
masses' own momenta:

    y = (x_1 .. x_N, p_1 .. p_N, gamma_1 .. gamma_ns, theta_1 .. theta_ns)     (flat)

with N masses and ns = N springs ('fixed-free') or N + 1 ('fixed-fixed', the second support at
span e_x). Spring a joins x_{a-1} and x_a (x_0 = 0), r_a = x_a - x_{a-1}, l_a = |r_a|. Every
spring carries gamma (a spring without a Maxwell element, beta_v = mu_neq = 0, keeps it at 0).
The free energy of spring a is eqs. (16)-(17) (psi below); its first derivatives are typed from
section 10, second derivatives are complex steps of them (exact to round-off). The field:

    dx_i/dt = p_i/m_i
    dp_i/dt = m_i g - psi_l(a=i) r_i/l_i + psi_l(a=i+1) r_{i+1}/l_{i+1}
    eta_a dgamma_a/dt = -psi_gamma
    Cap_a dtheta_a/dt = theta psi_{theta l} dl_a/dt + theta psi_{theta gamma} dgamma_a/dt
                        + eta (dgamma_a/dt)^2 + sum_links kappa (theta_b - theta_a)

E = sum |p|^2/(2m) - m g.x + sum u_a, u = psi + theta s, S = sum s_a, s = -psi_theta.
"""
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

COMPLEX_STEP = 1e-30


@dataclass(frozen=True)
class Spring:
    """One spring's data in SI units, the names of the pendulum's &model fields (Table 1)."""
    natural_length: float
    mu_eq_const: float
    mu_eq_slope: float = 0.0
    beta: float = 0.0
    heat_capacity: float = 10.0
    theta_ref: float = 300.0
    beta_v: float = 0.0
    mu_neq_const: float = 0.0
    mu_neq_slope: float = 0.0
    viscosity_const: float = 100.0
    viscosity_activation: float = 10.0


@dataclass
class Chain:
    """N masses, their springs (N or N + 1) and one conductivity per link (ns - 1)."""
    masses: np.ndarray
    springs: list
    conductivity: np.ndarray
    gravity: np.ndarray
    ends: str = "fixed-free"
    span: float = 0.0
    dim: int = field(init=False)

    def __post_init__(self):
        self.masses = np.asarray(self.masses, dtype=float)
        self.conductivity = np.asarray(self.conductivity, dtype=float)
        self.gravity = np.asarray(self.gravity, dtype=float)
        self.dim = len(self.gravity)
        n = len(self.masses)
        assert self.ends in ("fixed-free", "fixed-fixed"), self.ends
        assert len(self.springs) == n + (self.ends == "fixed-fixed"), (n, len(self.springs))
        assert len(self.conductivity) == len(self.springs) - 1

    @property
    def n(self):
        return len(self.masses)

    @property
    def ns(self):
        return len(self.springs)


def spring_arrays(chain: Chain):
    """Each Spring field as an array over the springs (numpy evaluates all springs at once)."""
    return {name: np.array([getattr(s, name) for s in chain.springs]) for name in Spring.__dataclass_fields__}


# ---------------------------------------------------------------- the free energy (16)-(17)
def psi(k, l, theta, gamma):
    """psi = (1 + beta_v) psi_eq + mu_neq(theta) gamma^2 - beta_v gamma d_l psi_eq, eq. (16)."""
    L = np.log(l / k["natural_length"])
    mu = k["mu_eq_const"] - k["mu_eq_slope"] * (theta - k["theta_ref"])
    mu_neq = k["mu_neq_const"] - k["mu_neq_slope"] * (theta - k["theta_ref"])
    tr = k["theta_ref"]
    psi_eq = mu / 2 * L**2 - k["beta"] * (theta - tr) * L + k["heat_capacity"] * (theta - tr - theta * np.log(theta / tr))
    dpsi_eq_dl = (mu * L - k["beta"] * (theta - tr)) / l
    return (1 + k["beta_v"]) * psi_eq + mu_neq * gamma**2 - k["beta_v"] * gamma * dpsi_eq_dl


def psi_gradient(k, l, theta, gamma):
    """(psi_l, psi_theta, psi_gamma) as section 10 types them."""
    L = np.log(l / k["natural_length"])
    tr = k["theta_ref"]
    mu = k["mu_eq_const"] - k["mu_eq_slope"] * (theta - tr)
    mu_neq = k["mu_neq_const"] - k["mu_neq_slope"] * (theta - tr)
    W = (mu * L - k["beta"] * (theta - tr)) / l
    W_l = (mu * (1 - L) + k["beta"] * (theta - tr)) / l**2
    bv = k["beta_v"]
    psi_l = (1 + bv) * W - bv * gamma * W_l
    psi_theta = (-(1 + bv) * (k["mu_eq_slope"] * L**2 / 2 + k["beta"] * L + k["heat_capacity"] * np.log(theta / tr))
                 - k["mu_neq_slope"] * gamma**2 + bv * gamma * (k["mu_eq_slope"] * L + k["beta"]) / l)
    psi_gamma = 2 * mu_neq * gamma - bv * W
    return psi_l, psi_theta, psi_gamma


def psi_hessian(k, l, theta, gamma):
    """d/d(l, theta, gamma) of psi_gradient by complex steps: H[i][j] = d_j (psi_i)."""
    args = [np.asarray(v, dtype=complex) for v in (l, theta, gamma)]
    columns = []
    for j in range(3):
        shifted = list(args)
        shifted[j] = shifted[j] + 1j * COMPLEX_STEP
        columns.append([np.imag(g) / COMPLEX_STEP for g in psi_gradient(k, *shifted)])
    return [[columns[j][i] for j in range(3)] for i in range(3)]


def entropy_energy(k, l, theta, gamma):
    """(s, u) = (-psi_theta, psi + theta s) of each spring."""
    s = -psi_gradient(k, l, theta, gamma)[1]
    return s, psi(k, l, theta, gamma) + theta * s


def viscosity(k, theta):
    """eta(theta) = eta_cst exp(eta_theta (1/theta - 1/theta_ref)), eq. (17)."""
    return k["viscosity_const"] * np.exp(k["viscosity_activation"] * (1 / theta - 1 / k["theta_ref"]))


def capacity(k):
    """Cap = -theta psi_{theta theta} = (1 + beta_v) c."""
    return (1 + k["beta_v"]) * k["heat_capacity"]


# ---------------------------------------------------------------- state, field, E, S, J
def split(chain: Chain, y):
    """(x (N, dim), p (N, dim), gamma (ns), theta (ns)) of a flat state."""
    y = np.asarray(y, dtype=float)
    nd = chain.n * chain.dim
    x = y[:nd].reshape(chain.n, chain.dim)
    p = y[nd:2 * nd].reshape(chain.n, chain.dim)
    return x, p, y[2 * nd:2 * nd + chain.ns], y[2 * nd + chain.ns:]


def join(x, p, gamma, theta):
    return np.concatenate([np.ravel(x), np.ravel(p), np.ravel(gamma), np.ravel(theta)])


def nodes(chain: Chain, x):
    """x_0 = 0, x_1 .. x_N and, 'fixed-fixed', x_{N+1} = span e_x."""
    rows = [np.zeros(chain.dim), *x]
    if chain.ends == "fixed-fixed":
        end = np.zeros(chain.dim)
        end[0] = chain.span
        rows.append(end)
    return np.array(rows)


def spring_vectors(chain: Chain, x):
    """r_a = x_a - x_{a-1} (ns, dim) and l_a."""
    r = np.diff(nodes(chain, x), axis=0)
    return r, np.linalg.norm(r, axis=1)


def conduction(chain: Chain, theta):
    """sum over the links of spring a of kappa (theta_b - theta_a); the ends are adiabatic."""
    flow = chain.conductivity * (theta[1:] - theta[:-1])       # into spring a from a + 1
    heat = np.zeros(chain.ns)
    heat[:-1] += flow
    heat[1:] -= flow
    return heat


def rhs(chain: Chain):
    """The field f(t, y) of section 10 in the temperature variable."""
    k = spring_arrays(chain)
    cap = capacity(k)

    def f(t, y):
        x, p, gamma, theta = split(chain, y)
        r, l = spring_vectors(chain, x)
        v = p / chain.masses[:, None]
        psi_l, _, psi_gamma = psi_gradient(k, l, theta, gamma)
        hessian = psi_hessian(k, l, theta, gamma)
        psi_theta_l, psi_theta_gamma = hessian[1][0], hessian[1][2]
        eta = viscosity(k, theta)
        dgamma = -psi_gamma / eta
        pull = psi_l[:, None] * r / l[:, None]                   # tension along r_a
        dp = chain.masses[:, None] * chain.gravity[None, :] - pull[:chain.n]
        dp[:chain.ns - 1] += pull[1:][:chain.n]
        v_nodes = np.vstack([np.zeros(chain.dim), v, np.zeros((chain.ns - chain.n, chain.dim))])
        dl = np.sum(r * np.diff(v_nodes, axis=0), axis=1) / l
        dtheta = (theta * psi_theta_l * dl + theta * psi_theta_gamma * dgamma + eta * dgamma**2
                  + conduction(chain, theta)) / cap
        return join(v, dp, dgamma, dtheta)
    return f


def energy_entropy(chain: Chain, y):
    """(E, S) = (T + V_g + sum u_a, sum s_a)."""
    k = spring_arrays(chain)
    x, p, gamma, theta = split(chain, y)
    _, l = spring_vectors(chain, x)
    s, u = entropy_energy(k, l, theta, gamma)
    kinetic = np.sum(p**2 / (2 * chain.masses[:, None]))
    gravity = -np.sum(chain.masses * (x @ chain.gravity))
    return kinetic + gravity + u.sum(), s.sum()


def entropy_production(chain: Chain, y):
    """(each viscous branch's eta (dgamma/dt)^2/theta, each link's kappa (theta_a - theta_b)^2/(theta_a theta_b))."""
    k = spring_arrays(chain)
    x, p, gamma, theta = split(chain, y)
    _, l = spring_vectors(chain, x)
    eta = viscosity(k, theta)
    rate = -psi_gradient(k, l, theta, gamma)[2] / eta
    links = chain.conductivity * (theta[:-1] - theta[1:])**2 / (theta[:-1] * theta[1:])
    return eta * rate**2 / theta, links


def angular_momentum(chain: Chain, y):
    """J = sum_i x_i x p_i: three components in 3D, the scalar in 2D, nothing in 1D."""
    x, p, _, _ = split(chain, y)
    if chain.dim == 1:
        return np.zeros(0)
    if chain.dim == 2:
        return np.array([np.sum(x[:, 0] * p[:, 1] - x[:, 1] * p[:, 0])])
    return np.cross(x, p).sum(axis=0)


def conserved_momenta(chain: Chain, y):
    """The momenta section 10's table keeps for this scene (an empty array where none is)."""
    j = angular_momentum(chain, y)
    g = chain.gravity
    if chain.ends == "fixed-free":
        if chain.dim == 3:
            return j if not np.any(g) else np.array([j @ g / np.linalg.norm(g)])
        return j if chain.dim == 2 and not np.any(g) else np.zeros(0)
    if chain.dim == 3 and not np.any(g[1:]):
        return j[:1]
    return np.zeros(0)


def solve(chain: Chain, y0, times, method="DOP853", rtol=1e-12, atol=1e-12):
    """The solution at `times` (rows) by SciPy."""
    times = np.atleast_1d(np.asarray(times, dtype=float))
    solution = solve_ivp(rhs(chain), (0.0, times[-1]), np.asarray(y0, dtype=float), method=method,
                         rtol=rtol, atol=atol, t_eval=times)
    assert solution.success, solution.message
    return solution.y.T


# ---------------------------------------------------------------- the paper's pendulum as a chain
def paper_chain():
    """N = 2 'fixed-free' in 3D with Table 1: spring 1 without a Maxwell element, spring 2 with it."""
    common = dict(mu_eq_const=200.0, mu_eq_slope=0.5, beta=0.02, heat_capacity=10.0, theta_ref=300.0,
                  viscosity_const=100.0, viscosity_activation=10.0)
    springs = [Spring(natural_length=1.5, **common),
               Spring(natural_length=2.0, beta_v=0.5, mu_neq_const=5.0, mu_neq_slope=0.1, **common)]
    return Chain(masses=[1.0, 1.0], springs=springs, conductivity=[1.0], gravity=[0.0, 0.0, -9.81])


def from_pendulum(q1, q2, p1, p2):
    """The chain's (x, p) from the pendulum's relative q2 = x2 - x1 and p1 = P1 + P2, p2 = P2."""
    q1, q2, p1, p2 = (np.asarray(v, dtype=float) for v in (q1, q2, p1, p2))
    return np.array([q1, q1 + q2]), np.array([p1 - p2, p2])


def to_pendulum(x, p):
    """(q1, q2, p1, p2) of the pendulum from the chain's absolute (x, p) of two masses."""
    return x[0], x[1] - x[0], p[0] + p[1], p[1]


PAPER_INITIAL = join(*from_pendulum([1.0, 0.0, 0.0], [3.0, 0.0, 0.0], [0.0, 0.0, 0.0], [-1.0, -1.0, 0.0]),
                     [0.0, 0.0], [280.0, 350.0])


# ---------------------------------------------------------------- the continuum family
@dataclass(frozen=True)
class Rod:
    """A thermoviscoelastic rod (section 10's table): per unit length or per cross-section, SI."""
    length: float
    mass_per_length: float
    axial_stiffness: float           # EA [N]
    stiffness_slope: float = 0.0     # -d(EA)/dtheta [N/K], a softening rate (the paper's sign)
    thermal_stress: float = 0.0      # E A alpha [N/K]
    heat_capacity: float = 1.0       # c [J/(K m)]
    beta_v: float = 0.0
    maxwell_stiffness: float = 0.0   # E^neq A [N], half the Maxwell modulus (mu^neq gamma^2)
    maxwell_slope: float = 0.0       # -d(E^neq A)/dtheta [N/K]
    viscosity: float = 1.0           # eta A [N s]
    viscosity_activation: float = 0.0
    conductivity: float = 0.0        # k A [W m/K]
    theta_ref: float = 300.0


def rod_chain(rod: Rod, n_springs, ends, gravity, span=None):
    """The chain of n_springs elements of length h = L/n_springs, masses lumped to the nodes."""
    h = rod.length / n_springs
    spring = Spring(natural_length=h, mu_eq_const=rod.axial_stiffness * h, mu_eq_slope=rod.stiffness_slope * h,
                    beta=rod.thermal_stress * h, heat_capacity=rod.heat_capacity * h, theta_ref=rod.theta_ref,
                    beta_v=rod.beta_v, mu_neq_const=rod.maxwell_stiffness / h, mu_neq_slope=rod.maxwell_slope / h,
                    viscosity_const=rod.viscosity / h, viscosity_activation=rod.viscosity_activation)
    n_masses = n_springs if ends == "fixed-free" else n_springs - 1
    masses = np.full(n_masses, rod.mass_per_length * h)
    if ends == "fixed-free":
        masses[-1] /= 2
    return Chain(masses=masses, springs=[spring] * n_springs, conductivity=np.full(n_springs - 1, rod.conductivity / h),
                 gravity=gravity, ends=ends, span=rod.length if span is None else span)


# ---------------------------------------------------------------- exact linear modes
def base_state(chain: Chain, theta0):
    """The uniform stretch of a 1D 'fixed-fixed' chain of identical springs: (l_s, gamma_0, y*)."""
    assert chain.dim == 1 and chain.ends == "fixed-fixed"
    k = chain.springs[0].__dict__
    l_s = chain.span / chain.ns
    tr = k["theta_ref"]
    L = np.log(l_s / k["natural_length"])
    W = ((k["mu_eq_const"] - k["mu_eq_slope"] * (theta0 - tr)) * L - k["beta"] * (theta0 - tr)) / l_s
    mu_neq = k["mu_neq_const"] - k["mu_neq_slope"] * (theta0 - tr)
    gamma0 = k["beta_v"] * W / (2 * mu_neq) if k["beta_v"] else 0.0
    x = (np.arange(1, chain.n + 1) * l_s)[:, None]
    y = join(x, np.zeros_like(x), np.full(chain.ns, gamma0), np.full(chain.ns, theta0))
    return l_s, gamma0, y


def linear_coefficients(chain: Chain, theta0):
    """Second derivatives of psi at the base state, Cap, eta and m, kappa of the uniform chain."""
    k = spring_arrays(chain)
    k1 = {name: value[0] for name, value in k.items()}
    l_s, gamma0, _ = base_state(chain, theta0)
    h = psi_hessian(k1, l_s, theta0, gamma0)
    return dict(ll=h[0][0], lt=h[0][1], lg=h[0][2], tl=h[1][0], tg=h[1][2], gl=h[2][0], gt=h[2][1], gg=h[2][2],
                cap=capacity(k1), eta=viscosity(k1, theta0), m=chain.masses[0], kappa=chain.conductivity[0],
                theta0=theta0)


def mode_generator(c, n, k):
    """A_k of section 10 on (U, P, G, Theta) for mode k = 1..n, or on (G, Theta) for k = 0."""
    sigma = np.sin(k * np.pi / (2 * (n + 1)))
    if k == 0:
        dg = np.array([-c["gg"], -c["gt"]]) / c["eta"]
        return np.array([dg, c["theta0"] * c["tg"] * dg / c["cap"]])
    dU = [0, 1 / c["m"], 0, 0]
    dP = [-4 * sigma**2 * c["ll"], 0, -2 * sigma * c["lg"], -2 * sigma * c["lt"]]
    dG = np.array([-2 * sigma * c["gl"], 0, -c["gg"], -c["gt"]]) / c["eta"]
    dT = (c["theta0"] * c["tl"] * 2 * sigma * np.array([0, 1 / c["m"], 0, 0]) + c["theta0"] * c["tg"] * dG
          - 4 * sigma**2 * c["kappa"] * np.array([0, 0, 0, 1])) / c["cap"]
    return np.array([dU, dP, dG, dT])


def cayley(a, dt):
    """The midpoint rule's step map (I - dt A/2)^-1 (I + dt A/2)."""
    eye = np.eye(len(a))
    return np.linalg.solve(eye - dt / 2 * a, eye + dt / 2 * a)


def elastic_cayley(omega, m, dt):
    """The 2 x 2 map of the elastic rung in closed form: 1/(1 + dt^2 w^2/4) [[c, dt/m], [-dt m w^2, c]]."""
    c = 1 - dt**2 * omega**2 / 4
    return np.array([[c, dt / m], [-dt * m * omega**2, c]]) / (1 + dt**2 * omega**2 / 4)


def linear_system(c, n):
    """The linearised equations of section 10 in nodal form, on (u (n), p (n), g (n+1), T (n+1))."""
    ns = n + 1
    D = np.zeros((ns, n))                                        # e = D u: e_a = u_a - u_{a-1}
    for a in range(ns):
        if a < n:
            D[a, a] = 1.0
        if a > 0:
            D[a, a - 1] = -1.0
    lap = -2 * np.eye(ns) + np.eye(ns, k=1) + np.eye(ns, k=-1)  # adiabatic Laplacian
    lap[0, 0] = lap[-1, -1] = -1.0
    size = 2 * n + 2 * ns
    u, p, g, t = (slice(0, n), slice(n, 2 * n), slice(2 * n, 2 * n + ns), slice(2 * n + ns, size))
    a = np.zeros((size, size))
    a[u, p] = np.eye(n) / c["m"]
    a[p, u] = -D.T @ (c["ll"] * D)                               # n_{i+1} - n_i = -(D^T n)_i
    a[p, g] = -D.T * c["lg"]
    a[p, t] = -D.T * c["lt"]
    a[g, u] = -c["gl"] * D / c["eta"]
    a[g, g] = -c["gg"] * np.eye(ns) / c["eta"]
    a[g, t] = -c["gt"] * np.eye(ns) / c["eta"]
    a[t, :] = c["theta0"] * c["tg"] * a[g, :] / c["cap"]
    a[t, p] += c["theta0"] * c["tl"] * D / (c["m"] * c["cap"])
    a[t, t] += c["kappa"] * lap / c["cap"]
    return a


def modal_amplitudes(n, state, k):
    """(U, P, G, Theta) of mode k >= 1, or (G, Theta) of k = 0, of a nodal linear state."""
    ns = n + 1
    u, p, g, t = state[:n], state[n:2 * n], state[2 * n:2 * n + ns], state[2 * n + ns:]
    sine = np.sin(k * np.pi * np.arange(1, n + 1) / ns)
    cosine = np.cos(k * np.pi * (np.arange(1, ns + 1) - 0.5) / ns)
    weight = (2.0 - (k == 0)) / ns
    spring = [weight * g @ cosine, weight * t @ cosine]
    return np.array(spring if k == 0 else [2 / ns * u @ sine, 2 / ns * p @ sine, *spring])


def mode_state(n, k, amplitudes):
    """The nodal linear state of mode k with the given amplitudes (as modal_amplitudes returns)."""
    ns = n + 1
    sine = np.sin(k * np.pi * np.arange(1, n + 1) / ns)
    cosine = np.cos(k * np.pi * (np.arange(1, ns + 1) - 0.5) / ns)
    if k == 0:
        return np.concatenate([np.zeros(2 * n), amplitudes[0] * cosine, amplitudes[1] * cosine])
    U, P, G, T = amplitudes
    return np.concatenate([U * sine, P * sine, G * cosine, T * cosine])


# ---------------------------------------------------------------- the end state of an isolated chain
def end_state(chain: Chain, energy):
    """At rest, equal springs of length span/ns, one temperature theta* from E = ns u(l*, theta*,
    gamma*(theta*)), the dampers relaxed: (y*, theta*, S*). 'fixed-fixed', no gravity, identical springs."""
    assert chain.ends == "fixed-fixed" and not np.any(chain.gravity)
    assert all(s == chain.springs[0] for s in chain.springs)
    k = {name: value[0] for name, value in spring_arrays(chain).items()}
    l_star = chain.span / chain.ns

    def relaxed_gamma(theta):
        if not k["beta_v"]:
            return 0.0
        tr = k["theta_ref"]
        L = np.log(l_star / k["natural_length"])
        W = ((k["mu_eq_const"] - k["mu_eq_slope"] * (theta - tr)) * L - k["beta"] * (theta - tr)) / l_star
        return k["beta_v"] * W / (2 * (k["mu_neq_const"] - k["mu_neq_slope"] * (theta - tr)))

    def excess(theta):
        return chain.ns * entropy_energy(k, l_star, theta, relaxed_gamma(theta))[1] - energy

    theta_star = brentq(excess, 1.0, 5.0 * k["theta_ref"], xtol=1e-13, rtol=4 * np.finfo(float).eps)
    x = np.zeros((chain.n, chain.dim))
    x[:, 0] = np.arange(1, chain.n + 1) * l_star
    gamma = np.full(chain.ns, relaxed_gamma(theta_star))
    y = join(x, np.zeros_like(x), gamma, np.full(chain.ns, theta_star))
    return y, theta_star, energy_entropy(chain, y)[1]


def with_springs(chain: Chain, **changes):
    """The chain with every spring's fields changed alike."""
    return replace(chain, springs=[replace(s, **changes) for s in chain.springs])
