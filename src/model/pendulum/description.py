"""The double pendulum's rungs (docs/formulation.md sections 2-4 and 9): masses m1 and m2 at q1 and q1 + q2,
in space or in the plane, two springs with invariants C_a = q_a.q_a and gravity; on the thermal rungs the springs
have the free energy (16)-(17) and conduct heat, and on the thermoviscoelastic rungs spring 2 has a Maxwell
branch (gamma). One description with three switches, `rung(name, title, dimension, viscous, thermal)`, since the
rungs share every formula and differ by which columns exist: the paper's rung (spatial, thermoviscoelastic:
paper_pendulum), the planar one (planar_pendulum), the thermoelastic ones (thermoelastic_pendulum,
planar_thermoelastic_pendulum: beta^v = 0, no gamma) and the elastic ones (elastic_pendulum,
planar_elastic_pendulum: W_a = mu_{a,cst}/2 L_a^2 of mechanical subsystems, no tau, no S, no K0). The
constraints and the input stay in the hand-written src/model/pendulum/ (the generator writes no scene for them:
`model.scene = False`).

The springs are written as section 3 collects eq. (16)-(17): u_a = e_a + Cap_a (theta - theta_ref),
s_a = sigma_a + Cap_a ln(theta/theta_ref) of psi_a = u_a - theta s_a (the generator checks that they derive
from one), with the mechanical parts e_a and
sigma_a of L_a = ln(l_a/l_a^0) = ln(C_a/(l_a^0)^2)/2, 1/l_a = C_a^(-1/2) and gamma. The inverses
theta(s) and theta(u) are section 3's table. The generator (src/model/generator/generate_model.py)
writes NAME_potential.f90 and NAME_model.f90 of each rung from this file."""
import sympy as sp

from model_description import ENERGY_LEVEL, ENTROPY_LEVEL, ModelDescription


def rung(name, title, dimension, viscous, thermal=True):
    """The pendulum of `dimension` (3: spatial; 2: planar, y vertical) with (viscous) or without the Maxwell branch
    on spring 2 (the thermoelastic rung: beta^v = 0, no gamma, no mu_neq_*, viscosity_* or beta_v), and without
    the thermal parts (thermal=False, the elastic rung: no mu_eq_slope, heat_capacity, conductivity, theta_ref or
    beta), as docs/formulation.md section 9's table states each rung."""
    model = ModelDescription(name, title, "docs/formulation.md sections 2-4" + ("" if name == "paper_pendulum" else
                                                                                  " and 9"))
    model.scene = False
    model.differences = True         # U(b) - U(a) by log1p, expm1 and factored powers, as thermo_variable.f90 did
    model.continuous_field = True     # the relaxed schemes' field composed in z (no partials): issue 42 item 5
    model.rounding_scales = True      # U's scale |e| + Cap (theta + theta_ref), not |U|: the step check's ulps

    def parameter(name, units, default, meaning, **bounds):
        return model.parameter(name, units, default, meaning, **bounds)

    m1 = parameter("mass_1", "kg", 1.0, "m_1", minimum=0.0, exclusive=True, positive=True)
    m2 = parameter("mass_2", "kg", 1.0, "m_2", minimum=0.0, exclusive=True, positive=True)
    natural_length = [parameter(f"natural_length_{a}", "m", default, f"lambda_{a}^0", minimum=0.0, exclusive=True,
                                positive=True) for a, default in ((1, 1.5), (2, 2.0))]
    mu_eq_const = [parameter(f"mu_eq_const_{a}", "J", 200.0, f"mu^eq_{{{a},cst}}, eq. (17)") for a in (1, 2)]
    if not thermal:
        return elastic_rung(model, dimension, m1, m2, natural_length, mu_eq_const)
    mu_eq_slope = [parameter(f"mu_eq_slope_{a}", "J/K", 0.5, f"mu^eq_{{{a},theta}}, eq. (17)") for a in (1, 2)]
    if viscous:
        mu_neq_const = parameter("mu_neq_const", "J/m^2", 5.0, "mu^neq_{2,cst}, eq. (17)")
        mu_neq_slope = parameter("mu_neq_slope", "J/(K m^2)", 0.1, "mu^neq_{2,theta}, eq. (17)")
    heat_capacity = [parameter(f"heat_capacity_{a}", "J/K", 10.0, f"c_{a}^0, eq. (16)", minimum=0.0, exclusive=True,
                               positive=True) for a in (1, 2)]
    if viscous:
        viscosity_const = parameter("viscosity_const", "J s/m^2", 100.0, "eta_cst, eq. (17)", minimum=0.0,
                                    exclusive=True, positive=True)
        viscosity_activation = parameter("viscosity_activation", "K", 10.0, "eta_theta, eq. (17)")
    conductivity = parameter("conductivity", "J/(K s)", 1.0, "kappa, eq. (12)", minimum=0.0)
    theta_ref = parameter("theta_ref", "K", 300.0, "theta_ref", minimum=0.0, exclusive=True, positive=True)
    beta = parameter("beta", "J/K", 0.02, "the thermal coupling beta")
    beta_v = parameter("beta_v", "1", 0.5, "the Maxwell coupling beta^v", minimum=0.0) if viscous else 0
    q, p = mechanics(model, dimension, m1, m2)
    if viscous:
        gamma = model.position("gamma", "m", 0.0, "the Maxwell element's internal length (spring 2)")

    springs = []
    for a in (1, 2):
        cap = heat_capacity[a - 1] if a == 1 else (1 + beta_v)*heat_capacity[1]      # Cap_2 = (1 + beta^v) c_2^0
        spring = model.subsystem(str(a), f"spring {a}", initial_temperature=300.0,
                                 tau_scales={"entropy": cap, "temperature": theta_ref, "internal_energy": cap*theta_ref},
                                 label=f"spring {a}")
        c = spring.invariant("C", sum(x**2 for x in q[a - 1]), scale=natural_length[a - 1]**2, positive=True)
        log_stretch = sp.log(c/natural_length[a - 1]**2)/2                              # L_a = ln(l_a/l_a^0)
        inverse_length = c**sp.Rational(-1, 2)                                          # 1/l_a
        stiffness = mu_eq_const[a - 1] + mu_eq_slope[a - 1]*theta_ref                   # a_a
        e = stiffness/2*log_stretch**2 + beta*theta_ref*log_stretch
        sigma = mu_eq_slope[a - 1]/2*log_stretch**2 + beta*log_stretch
        if a == 2 and viscous:
            g = spring.invariant("gamma", gamma, scale=1)
            maxwell = mu_neq_const + mu_neq_slope*theta_ref                             # A
            e = (1 + beta_v)*e + maxwell*g**2 - beta_v*g*(stiffness*log_stretch + beta*theta_ref)*inverse_length
            sigma = (1 + beta_v)*sigma + mu_neq_slope*g**2 - beta_v*g*(mu_eq_slope[1]*log_stretch + beta)*inverse_length
        theta = sp.Symbol("theta", positive=True)
        spring.energy_and_entropy(e + cap*(theta - theta_ref), sigma + cap*sp.log(theta/theta_ref), theta)
        spring.inverses = {"entropy": theta_ref*sp.exp((ENTROPY_LEVEL - sigma)/cap),
                           "internal_energy": theta_ref + (ENERGY_LEVEL - e)/cap}
        springs.append(spring)

    # K0 of eq. (12): Theta_2/eta(Theta_2) on gamma (viscous rungs), kappa Theta_1 Theta_2 [[1, -1], [-1, 1]] on
    # (tau_1, tau_2).
    theta_1, theta_2 = (spring.temperature for spring in springs)
    if viscous:
        eta = viscosity_const*sp.exp(viscosity_activation*(1/theta_2 - 1/theta_ref))
        model.friction(gamma, gamma, theta_2/eta)
    tau_1, tau_2 = (model.tau(spring) for spring in springs)
    conduction = conductivity*theta_1*theta_2
    model.friction(tau_1, tau_1, conduction)
    model.friction(tau_2, tau_2, conduction)
    model.friction(tau_1, tau_2, -conduction)
    model.theta_r = theta_ref
    model.describe(temperature="spring temperatures", energy="total energy E = T + V_g + U_1 + U_2",
                   entropy="total entropy S = S_1 + S_2",
                   metric_scales="C by (l^0)^2, gamma by 1 m, theta by theta_ref, s by Cap, u by Cap theta_ref")
    maxwell_rate = ["dgamma/dt = (Theta_2/eta(Theta_2)) (dS_2/dgamma - (dU_2/dgamma)/Theta_2),"] if viscous else []
    maxwell_heat = " - [a = 2] (dU_2/dgamma)/(dU_2/dtau) dgamma/dt" if viscous else ""
    model.field_text = "\n".join(["dq/dt = m^-1 p,  dp_a/dt = -grad_qa V_g - 2 q_a (dU_a/dC - Theta_a dS_a/dC),",
                                  *maxwell_rate, f"dtau_a/dt = -2 (dS_a/dC) q_a.(m^-1 p)_a/(dS_a/dtau){maxwell_heat}",
                                  "+ kappa (Theta_b - Theta_a)/(dU_a/dtau)  (docs/formulation.md section 4)"])
    return model


def mechanics(model, dimension, m1, m2):
    """Every rung's mechanics: gravity's parameters, the columns q1, q2, p1, p2 (`dimension` components each),
    T + V_g, L0 canonical in each (q_a, p_a) component and J = q1 x p1 + q2 x p2; returns q and p."""
    axes = "xyz"[:dimension]
    vector = range(dimension)
    gravity = [model.parameter(f"gravity_{axis}", "m/s^2", default, f"g_{axis}")
               for axis, default in zip(axes, (0, 0, -9.81) if dimension == 3 else (0, -9.81))]
    # z = (q1, q2, p1, p2, [gamma,] [tau1, tau2]), section 2's order; q2 is m2's position relative to m1.
    q = [[model.position(f"q{a}_{axis}", "m", 0.0, f"q_{a}'s {axis} component") for axis in axes] for a in (1, 2)]
    p = [[model.momentum(f"p{a}_{axis}", "N s", 0.0, f"p_{a}'s {axis} component", dataset=False) for axis in axes]
         for a in (1, 2)]
    # T = 1/2 p.m^-1 p with m^-1 = [[I/m1, -I/m1], [-I/m1, (m1+m2)/(m1 m2) I]] (eq. (1)); V_g = -(m1+m2) g.q1 - m2 g.q2.
    kinetic = sum(p[0][i]**2/(2*m1) - p[0][i]*p[1][i]/m1 + (m1 + m2)/(2*m1*m2)*p[1][i]**2 for i in vector)
    gravity_potential = -sum(((m1 + m2)*q[0][i] + m2*q[1][i])*gravity[i] for i in vector)
    model.mechanical_energy = kinetic + gravity_potential
    for a in range(2):
        for i in vector:
            model.canonical_pair(q[a][i], p[a][i])
    model.angular_momentum([(q[0], p[0]), (q[1], p[1])], gravity)
    return q, p


def elastic_rung(model, dimension, m1, m2, natural_length, stiffness):
    """The elastic rung (section 9's table): each spring a mechanical subsystem of C_a alone with the stored energy
    W_a = mu_{a,cst}/2 L_a^2, the free energy (16) at theta_ref without its thermal terms; no S, no K0."""
    q, _ = mechanics(model, dimension, m1, m2)
    for a in (1, 2):
        spring = model.mechanical_subsystem(str(a), f"spring {a}", label=f"spring {a}")
        c = spring.invariant("C", sum(x**2 for x in q[a - 1]), scale=natural_length[a - 1]**2, positive=True)
        log_stretch = sp.log(c/natural_length[a - 1]**2)/2                              # L_a = ln(l_a/l_a^0)
        spring.stored_energy(stiffness[a - 1]/2*log_stretch**2)
    model.describe(temperature="spring temperatures", energy="total energy E = T + V_g + W_1 + W_2",
                   entropy="total entropy S = S_1 + S_2", metric_scales="C by (l^0)^2")
    model.field_text = "dq/dt = m^-1 p,  dp_a/dt = -grad_qa V_g - 2 q_a dW_a/dC  (docs/formulation.md section 9)"
    return model


# The rungs of docs/formulation.md section 9's ladder, each spatial and planar.
models = [rung("paper_pendulum", "the thermoviscoelastic double pendulum", 3, viscous=True),
          rung("planar_pendulum", "the planar thermoviscoelastic double pendulum", 2, viscous=True),
          rung("thermoelastic_pendulum", "the thermoelastic double pendulum", 3, viscous=False),
          rung("planar_thermoelastic_pendulum", "the planar thermoelastic double pendulum", 2, viscous=False),
          rung("elastic_pendulum", "the elastic double pendulum", 3, viscous=False, thermal=False),
          rung("planar_elastic_pendulum", "the planar elastic double pendulum", 2, viscous=False, thermal=False)]
