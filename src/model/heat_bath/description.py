"""The heat-bath oscillator (docs/formulation.md section 11): a mass m on a spring of stiffness k,
its motion damped by a friction that moves the kinetic energy into a heat bath of heat capacity c
and entropy S. E = p^2/(2m) + k q^2/2 + U(S) with U(S) = c theta_ref exp(S/c), the internal energy
of a bath of constant heat capacity (theta = dU/dS = theta_ref exp(S/c)). The friction force is
-(nu + nu_3 v^2) v with v = p/m: a linear and a cubic drag, a friction that depends on the state.

The kinetic energy p^2/(2m) is mechanical energy, with the spring's k q^2/2; the bath's U(S) alone is
its subsystem (its one invariant is tau). The drag sees the velocity v = p/m from the state: K0 is
(nu + nu_3 v^2) Theta w w^T with w = e_p - v e_tau, whose (p, p) entry (nu + nu_3 v^2) Theta is the
drag and whose (p, tau) and (tau, tau) entries make K0 annihilate M_E^T grad E = (k q, v, 1), so
K grad E = 0 (docs/formulation.md section 11 derives K dE = 0 and L dS = 0). Through Mielke's split
K = M_E K0 M_E^T the drag's power goes to tau. The generator (src/model/generator/generate_model.py)
writes heat_bath_potential.f90, heat_bath_model.f90 and heat_bath_scene.f90 from this file."""
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

bath = model.subsystem("bath", "the heat bath", initial_temperature=300.0,
                       tau_scales={"entropy": c, "temperature": theta_ref, "internal_energy": c*theta_ref})
s = sp.Symbol("s", real=True)
bath.internal_energy(c*theta_ref*sp.exp(s/c), s)

model.mechanical_energy = p**2/(2*m) + k*q**2/2
model.canonical_pair(q, p)
# The drag on the velocity v = p/m, taken from the state (K0(z, partials)); a scheme evaluates it at z_mid,
# where p/m is the mechanical energy's exact midpoint gradient in p: K0 M_E^T DE = 0 in the step too.
velocity = p/m
drag = (nu + nu_3*velocity**2)*bath.temperature
tau = model.tau(bath)
model.friction(p, p, drag)
model.friction(p, tau, -drag*velocity)
model.friction(tau, tau, drag*velocity**2)
model.theta_r = theta_ref
model.field_text = """dq/dt = v,  dp/dt = -k q - (nu + nu_3 v^2) v,  v = p/m,
dS/dt = (nu + nu_3 v^2) v^2/Theta (in the entropy variable)"""
