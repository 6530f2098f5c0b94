"""The two gas containers (docs/formulation.md section 8): a piston of unit mass at q between two
containers of volumes v_1 = q and v_2 = 2 - q, each an ideal monatomic gas (nondimensional) with
U_a = (exp(s_a)/v_a)^(2/3), so theta_a = dU_a/ds_a = 2 U_a/3. E = p^2/2 + U_1 + U_2, S = S_1 + S_2;
L0 is canonical in (q, p) and K0 = friction [[1, -1], [-1, 1]] on (tau_1, tau_2), whatever the
state: heat crosses the piston at the rate friction (1/theta_1 - 1/theta_2). The piston's momentum
is no first integral and the model reports no momenta. The generator
(src/model/generator/generate_model.py) writes gas_containers_potential.f90, gas_containers_model.f90
and gas_containers_scene.f90 from this file."""
import sympy as sp

from model_description import ENERGY_LEVEL, TEMPERATURE, ModelDescription

model = ModelDescription("gas_containers", "the two gas containers", "docs/formulation.md section 8",
                         energy_units="1", entropy_units="1", temperature_units="1")

friction = model.parameter("friction", "1", 8.0, "K0 = friction [[1, -1], [-1, 1]] on the containers' "
                           "thermodynamic variables", minimum=0.0)

q = model.position("q", "1", 1.0, "the piston, the first container's volume (the second's is 2 - q)",
                   minimum=0.0, exclusive=True, maximum=2.0)
p = model.momentum("p", "1", 2.0, "the piston's momentum (unit mass)", dataset=False)

total_volume = 2
containers = []
for number, volume in ((1, q), (2, total_volume - q)):
    container = model.subsystem(str(number), f"container {number}", initial_temperature=None,
                                tau_scales={"entropy": 1, "temperature": 1, "internal_energy": 1},
                                label=f"container {number}")
    v = container.invariant("v", volume, scale=1, positive=True)
    s = sp.Symbol("s", real=True)
    container.internal_energy(sp.exp(sp.Rational(2, 3)*(s - sp.log(v))), s)
    # s(v, theta) and s(v, u) as section 8 writes them (SymPy's own, log(3 sqrt(6) theta^(3/2) v/4), overflows
    # sooner and differs in rounding from the model it replaces)
    container.inverses = {"temperature": sp.log(v) + sp.Rational(3, 2)*sp.log(sp.Rational(3, 2)*TEMPERATURE),
                          "internal_energy": sp.log(v) + sp.Rational(3, 2)*sp.log(ENERGY_LEVEL)}
    containers.append(container)

model.mechanical_energy = p**2/2
model.canonical_pair(q, p)
first, second = (model.tau(container) for container in containers)
model.friction(first, first, friction)
model.friction(second, second, friction)
model.friction(first, second, -friction)
model.theta_r = sp.Integer(1)
model.initial_thermal_field("entropy", "entropy", [1.5, 3.0], "the containers' entropies, whatever the "
                            "thermodynamic variable")
model.initial_domain = ("entropies whose containers' internal energies (exp(entropy(a))/v_a)^(2/3), v_1 = q and "
                        "v_2 = 2 - q, are finite (below 1e277) and > 0")
model.describe(temperature="temperatures of the two gas containers", energy="total energy E = p^2/2 + U_1 + U_2",
               entropy="total entropy S = S_1 + S_2",
               metric_scales="every invariant by 1 (the model is nondimensional)")
model.field_text = """dq/dt = p,  dp/dt = -(dU_1/dv - Theta_1 dS_1/dv) + (dU_2/dv - Theta_2 dS_2/dv),
dtau_a/dt = -(dS_a/dv) w_a/(dS_a/dtau) + friction (1/Theta_a - 1/Theta_b)/(dU_a/dtau), w_1 = p, w_2 = -p"""
