"""The heat-bath oscillator (docs/formulation.md section 11): a mass m on a spring of stiffness k,
its motion damped by a friction that moves the kinetic energy into a heat bath of heat capacity c
and entropy S. E = p^2/(2m) + k q^2/2 + U(S) with U(S) = c theta_ref exp(S/c), the internal energy
of a bath of constant heat capacity (theta = dU/dS = theta_ref exp(S/c)). The friction force is
-(nu + nu_3 v^2) v with v = p/m: a linear and a cubic drag, a friction that depends on the state.

The mass's kinetic energy belongs to the bath's U_a (its invariants are p and tau), so that K0,
which sees the subsystems' partials (src/structure/model_interface.f90), sees the velocity
v = dU_a/dp - Theta dS_a/dp and the temperature Theta: K0 = (nu + nu_3 v^2) Theta on (p, p). Through Mielke's
split K = M_E K0 M_E^T then couples p with tau (docs/formulation.md section 11 derives K dE = 0
and L dS = 0). The generator (src/model/generator/generate_model.py) writes
heat_bath_potential.f90, heat_bath_model.f90 and heat_bath_scene.f90 from this file."""
import sympy as sp

from model_description import ModelDescription

model = ModelDescription("heat_bath", "a harmonic oscillator whose friction heats a bath",
                         "docs/formulation.md section 11")

m = model.parameter("mass", "kg", 1.0, "the oscillator's mass m", minimum=0.0, exclusive=True, positive=True)
k = model.parameter("stiffness", "N/m", 4.0, "the spring's stiffness k", minimum=0.0)
c = model.parameter("heat_capacity", "J/K", 2.0, "the bath's heat capacity c", minimum=0.0, exclusive=True,
                    positive=True)
theta_ref = model.parameter("theta_ref", "K", 300.0, "the bath's temperature at S = 0", minimum=0.0,
                            exclusive=True, positive=True)
nu = model.parameter("friction", "kg/s", 0.5, "nu, the linear drag: force -nu v", minimum=0.0)
nu_3 = model.parameter("friction_cubic", "kg s/m^2", 0.1, "nu_3, the cubic drag: force -nu_3 v^3", minimum=0.0)

q = model.position("q", "m", 1.0, "the mass's displacement from the spring's rest")
p = model.momentum("p", "N s", 0.0, "the mass's momentum m dq/dt")

bath = model.subsystem("bath", "the heat bath and the moving mass", initial_temperature=300.0,
                       tau_scales={"entropy": c, "temperature": theta_ref, "internal_energy": c*theta_ref})
momentum = bath.invariant("p", p, scale=sp.sqrt(m*c*theta_ref))
s = sp.Symbol("s", real=True)
bath.internal_energy(momentum**2/(2*m) + c*theta_ref*sp.exp(s/c), s)

model.mechanical_energy = k*q**2/2
model.canonical_pair(q, p)
# The velocity dE/dp at fixed entropy, v = dU_a/dp - Theta dS_a/dp: p/m at a state in every thermodynamic
# variable (in the internal-energy variable dU_a/dp = 0 and the velocity lies in dS_a/dp).
velocity = bath.partial("U", "p") - bath.temperature*bath.partial("S", "p")
model.friction(p, p, (nu + nu_3*velocity**2)*bath.temperature)
model.theta_r = theta_ref
model.field_text = """dq/dt = v,  dp/dt = -k q - (nu + nu_3 v^2) v,  v = dU/dp - Theta dS/dp (p/m at a state),
dS/dt = (nu + nu_3 v^2) v^2/Theta (in the entropy variable)"""
