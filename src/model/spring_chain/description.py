"""The spring chain (docs/formulation.md section 10) as the elements it is made of, repeated along a line of points:
point a holds mass a (x_a, p_a) and spring a's gamma_a and tau_a; spring a joins points a-1 and a (x_0 = 0, the
support); each spring is the paper's (src/model/paper_spring/description.py, on the rung of `spring_law`). The
generator writes spring_chain_blocks.f90 from it: each element's part of f = L DE + K DS (eq. (8) with Mielke's
split, section 4), with its derivatives in the unknowns it touches and in its springs' partials, for 1, 2 and 3
dimensions and every rung. spring_chain_step and spring_chain_dmda loop over the elements a rank owns and add the
blocks into banded rows.

Why this form: the chain's field is a sum over elements of fixed size, so a description that states one element of
each kind (its points and springs as offsets from a, the rows it fills, its energy, L0 and K0) is the whole model
for every N, and the Jacobian is banded by construction (an element reaches at most one point either side). The
energies and matrices are the paper's, in SymPy as the other descriptions (generator/model_description.py); the
field is not typed here but composed by the generator. The rows an element fills say how the sum is split: a
spring's kinetic energy of its two ends is there only for the coupling of its heat to their velocities (M_S), so it
fills no x row (those are the mass's v)."""
from model_description import ChainDescription

model = ChainDescription("spring_chain", "a chain of N springs", "docs/formulation.md section 10",
                         spring="paper_spring", rungs={1: ("C",), 2: ("C", "tau"), 3: ("C", "gamma", "tau")})

# Spring a's invariant C_a = |x_a - x_{a-1}|^2.
model.invariant(lambda v: (v.x(0) - v.x(-1)).dot(v.x(0) - v.x(-1)))

# Mass a: T + V_g of its own point, L0 canonical.
model.element("mass", points=(0,), springs=(), rows=("x", "p"), parameters=("mass", "gravity"), canonical=True,
              energy=lambda v: v.p(0).dot(v.p(0))/(2*v.parameter("mass"))
              - v.parameter("mass")*v.vector("gravity").dot(v.x(0)))

# Spring a: its potentials; the kinetic energy of its ends (1/m = 0 at a support); K0 = Theta_a/eta(Theta_a) on gamma.
model.element("spring", points=(-1, 0), springs=(0,), rows=("p", "gamma", "tau"),
              parameters=("inverse_mass_left", "inverse_mass_right"), canonical=True,
              energy=lambda v: (v.p(-1).dot(v.p(-1))*v.parameter("inverse_mass_left")
                                + v.p(0).dot(v.p(0))*v.parameter("inverse_mass_right"))/2,
              friction=lambda v: {(("gamma", 0), ("gamma", 0)): v.theta(0)/v.viscosity(0)})

# Link (a, a+1): heat conducted between neighbouring springs, K0 = kappa Theta_a Theta_{a+1} [[1, -1], [-1, 1]].
model.element("link", points=(-1, 0, 1), springs=(0, 1), rows=("tau",), parameters=("conductivity",),
              friction=lambda v: {(("tau", a), ("tau", b)): (1 if a == b else -1)*v.parameter("conductivity")
                                  * v.theta(0)*v.theta(1) for a in (0, 1) for b in (0, 1)})
