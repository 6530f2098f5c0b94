"""The two gas containers, typed from their definitions for the tests (not from src/): a piston
of unit mass at q between containers of volumes q and 2 - q, each an ideal gas with internal
energy U_a = (exp(S_a)/v_a)^(2/3), so temperature theta_a = dU_a/dS_a = 2 U_a/3, pressure
-dU_a/dv_a = 2 U_a/(3 v_a); heat flows through the piston with the friction matrix
K0 = friction [[1, -1], [-1, 1]] on the entropies' conjugates, so that in entropy variables

    dq/dt = p,   dp/dt = P_1 - P_2,
    dS_1/dt = friction (1/theta_1 - 1/theta_2) / theta_1,   dS_2/dt likewise with 1 and 2 swapped,

E = p^2/2 + U_1 + U_2 is conserved and dS/dt = friction (1/theta_1 - 1/theta_2)^2 >= 0.
The reference solution is SciPy's DOP853 at rtol = atol = 1e-13."""
import numpy as np
from scipy.integrate import solve_ivp

TOTAL_VOLUME = 2.0


def energies(q, entropies):
    """U_1, U_2 of the containers at piston position q."""
    volumes = np.array([q, TOTAL_VOLUME - q])
    return (np.exp(np.asarray(entropies)) / volumes) ** (2.0 / 3.0)


def rhs(friction):
    """The field in (q, p, S_1, S_2)."""
    def field(t, y):
        q, p, s1, s2 = y
        u = energies(q, [s1, s2])
        theta = 2.0 * u / 3.0
        pressure = theta / np.array([q, TOTAL_VOLUME - q])
        flux = friction * (1.0 / theta[0] - 1.0 / theta[1])
        return [p, pressure[0] - pressure[1], flux / theta[0], -flux / theta[1]]
    return field


def energy(y):
    """E = p^2/2 + U_1 + U_2 at a state (q, p, S_1, S_2)."""
    return 0.5 * y[1] ** 2 + energies(y[0], y[2:]).sum()


def reference(y0, t_end, friction, times=None):
    """The solution at t_end (or at `times`), as rows (q, p, S_1, S_2)."""
    solution = solve_ivp(rhs(friction), (0.0, t_end), y0, method="DOP853", rtol=1e-13, atol=1e-13,
                         t_eval=[t_end] if times is None else times)
    assert solution.success, solution.message
    return solution.y.T


def entropy_of(volume, variable, tau):
    """A container's entropy from its state in another thermodynamic variable (U = 3 theta/2 = u)."""
    if variable == "entropy":
        return tau
    u = 1.5 * tau if variable == "temperature" else tau
    return np.log(volume) + 1.5 * np.log(u)
