"""The paper's spring (docs/formulation.md sections 3, 9 and 10), a shared element: the spring chain's assembly
(spring_chain_spring) and the double pendulum's fused step kernel (pendulum_step_kernel) both call it spring by
spring. Its potentials (U_a, S_a) in its invariants x_a = (C, [gamma,] [tau]) on each rung of the ladder, with the
spring's own data, and the viscosity eta(theta) of eq. (17). The generator writes paper_spring_potential.f90 alone
from it (`potential_only`: no model, no scene). A potential_only folder is the one kind of model folder whose modules
other model folders may use (tests/architecture/test_layers.py): it is an element, not a model.

The rungs, numbered by their invariant count as spring_chain_spring's rung_* are:
 1. elastic: x = C, U = W(C) = mu_eq_const/2 L^2 (the free energy (16) at theta_ref without beta), S = 0;
 2. thermoelastic: x = (C, tau), u = e + c (theta - theta_ref), s = sigma + c ln(theta/theta_ref) with section 3's
    e and sigma at beta^v = 0 (no Maxwell branch);
 3. thermoviscoelastic: x = (C, gamma, tau), section 3's e_2 and sigma_2 with the Maxwell branch and
    Cap = (1 + beta^v) c.
The pendulum's spring 1 is rung 2 with its data; its spring 2 is rung 3 (a thermoelastic pendulum's with
beta_v = mu_neq_const = mu_neq_slope = 0, so its potentials do not depend on gamma).
src/model/pendulum/description.py states the same law for the pendulum's generated rungs;
tests/unit/test_spring_chain_spring.pf checks the two agree. L = ln(l/l^0) = ln(C/(l^0)^2)/2 and 1/l = C^(-1/2)."""
import sympy as sp

from model_description import ENERGY_LEVEL, ENTROPY_LEVEL, TEMPERATURE, ModelDescription

model = ModelDescription("paper_spring", "the paper's spring", "docs/formulation.md sections 3, 9 and 10")
model.potential_only = True          # the element's potentials alone: the chain's and the pendulum's code assemble it
model.scene = False
model.differences = True             # U(b) - U(a), S(b) - S(a) by log1p, expm1 and factored powers
model.rounding_scales = True         # the thermal rungs' rounding scales from their terms (the step check's ulps)

# The element's data (spring_chain_spring's spring_data), in its order; defaults are Table 1's spring 2.
natural_length = model.parameter("natural_length", "m", 2.0, "l^0", minimum=0.0, exclusive=True, positive=True)
mu_eq_const = model.parameter("mu_eq_const", "J", 200.0, "mu^eq_cst, eq. (17)")
mu_eq_slope = model.parameter("mu_eq_slope", "J/K", 0.5, "mu^eq_theta, eq. (17)")
mu_neq_const = model.parameter("mu_neq_const", "J/m^2", 5.0, "mu^neq_cst, eq. (17)")
mu_neq_slope = model.parameter("mu_neq_slope", "J/(m^2 K)", 0.1, "mu^neq_theta, eq. (17)")
heat_capacity = model.parameter("heat_capacity", "J/K", 10.0, "c^0, eq. (16)", minimum=0.0, exclusive=True,
                                positive=True)
viscosity_const = model.parameter("viscosity_const", "N s/m", 100.0, "eta_cst, eq. (17)", minimum=0.0, exclusive=True,
                                  positive=True)
viscosity_activation = model.parameter("viscosity_activation", "K", 10.0, "eta_theta, eq. (17)")
theta_ref = model.parameter("theta_ref", "K", 300.0, "theta_ref", minimum=0.0, exclusive=True, positive=True)
beta = model.parameter("beta", "J/K", 0.02, "the thermal coupling beta")
beta_v = model.parameter("beta_v", "1", 0.5, "the Maxwell coupling beta^v", minimum=0.0)

C = sp.Symbol("C", real=True)
log_stretch = sp.log(C/natural_length**2)/2                  # L = ln(l/l^0)
inverse_length = C**sp.Rational(-1, 2)                       # 1/l

# Rung 1: the elastic spring, W = mu_eq_const/2 L^2 and no entropy.
model.stored_energy("elastic", "the elastic rung", [("C", natural_length**2)], mu_eq_const/2*log_stretch**2)

# Rungs 2 and 3: section 3's e and sigma, without and with the Maxwell branch.
theta = sp.Symbol("theta", positive=True)
stiffness = mu_eq_const + mu_eq_slope*theta_ref              # a = mu_cst + mu_theta theta_ref
for name, viscous in (("thermoelastic", False), ("thermoviscoelastic", True)):
    cap = (1 + beta_v)*heat_capacity if viscous else heat_capacity
    spring = model.subsystem(name, f"the {name} rung", initial_temperature=300.0,
                             tau_scales={"entropy": cap, "temperature": theta_ref, "internal_energy": cap*theta_ref})
    spring.invariant("C", C, scale=natural_length**2, positive=True)
    e = stiffness/2*log_stretch**2 + beta*theta_ref*log_stretch
    sigma = mu_eq_slope/2*log_stretch**2 + beta*log_stretch
    if viscous:
        g = spring.invariant("gamma", sp.Symbol("gamma", real=True), scale=1)
        maxwell = mu_neq_const + mu_neq_slope*theta_ref      # A
        e = (1 + beta_v)*e + maxwell*g**2 - beta_v*g*(stiffness*log_stretch + beta*theta_ref)*inverse_length
        sigma = (1 + beta_v)*sigma + mu_neq_slope*g**2 - beta_v*g*(mu_eq_slope*log_stretch + beta)*inverse_length
    spring.energy_and_entropy(e + cap*(theta - theta_ref), sigma + cap*sp.log(theta/theta_ref), theta)
    spring.inverses = {"entropy": theta_ref*sp.exp((ENTROPY_LEVEL - sigma)/cap),
                       "internal_energy": theta_ref + (ENERGY_LEVEL - e)/cap}

# eta(theta) of eq. (17), the viscous branch's rate (Theta/eta) y.
model.temperature_function("viscosity", "eta(theta) of eq. (17)",
                           viscosity_const*sp.exp(viscosity_activation*(1/TEMPERATURE - 1/theta_ref)))
