"""MODEL_NAME (docs/formulation.md section ?): say here what the model is, its state and its laws.

Started by `make new-model NAME=MODEL_NAME` from src/model/generator/description_template.py: a
mass on a spring whose linear drag heats a body of constant heat capacity. Edit the parts below
(model_description.py says what each states), then `make generate` writes
MODEL_NAME_potential.f90, MODEL_NAME_model.f90 and MODEL_NAME_scene.f90 beside this file, and two
lines in src/model/model_registry_lines.f90 register it:
    use MODEL_NAME_scene, only: MODEL_NAME_name, new_MODEL_NAME_scene
    model_entry(MODEL_NAME_name, new_MODEL_NAME_scene)
Then docs/input.md takes the rows `generate_model.py --input-rows` prints."""
import sympy as sp

from model_description import ModelDescription

model = ModelDescription("MODEL_NAME", "a mass on a spring whose drag heats a body", "docs/formulation.md section ?")

# Parameters of &model: name, units, default, meaning and the allowed range.
m = model.parameter("mass", "kg", 1.0, "the mass", minimum=0.0, exclusive=True, positive=True)
k = model.parameter("stiffness", "N/m", 1.0, "the spring's stiffness", minimum=0.0)
c = model.parameter("heat_capacity", "J/K", 1.0, "the body's heat capacity", minimum=0.0, exclusive=True,
                    positive=True)
theta_ref = model.parameter("theta_ref", "K", 300.0, "the body's temperature at S = 0", minimum=0.0, exclusive=True,
                            positive=True)
nu = model.parameter("friction", "kg/s", 0.1, "the linear drag", minimum=0.0)

# The mechanical columns of z with their &initial defaults; the subsystems add their tau columns.
q = model.position("q", "m", 1.0, "the displacement")
p = model.momentum("p", "N s", 0.0, "the momentum")

# A thermodynamic subsystem: its mechanical invariants (at most quadratic in z, with their typical
# sizes) and U_a(x, s) (or psi_a(x, theta) with free_energy); the generator derives the temperature
# and internal-energy forms.
body = model.subsystem("body", "the heated body and the moving mass", initial_temperature=300.0,
                       tau_scales={"entropy": c, "temperature": theta_ref, "internal_energy": c*theta_ref})
momentum = body.invariant("p", p, scale=sp.sqrt(m*c*theta_ref))
s = sp.Symbol("s", real=True)
body.internal_energy(momentum**2/(2*m) + c*theta_ref*sp.exp(s/c), s)

# E = mechanical energy + sum U_a; L0 and K0 of eq. (8) (K0 in the subsystems' partials and temperatures).
model.mechanical_energy = k*q**2/2
model.canonical_pair(q, p)
model.friction(p, p, nu*body.temperature)
model.theta_r = theta_ref
model.field_text = "dq/dt = v, dp/dt = -k q - nu v, v = dU/dp"
