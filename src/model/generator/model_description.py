"""The description format of a GENERIC model (docs/development.md, Adding a model): what a
description file states, as SymPy expressions, and what the generator (generate_model.py) reads.

A description is a Python module that builds one `ModelDescription` named `model`:

    model = ModelDescription("heat_bath", "a harmonic oscillator in a heat bath", ...)
    m = model.parameter("mass", "kg", 1.0, minimum=0.0, exclusive=True)   # a sympy Symbol
    q = model.position("q", "m", 1.0, "the displacement")                 # a state column
    p = model.momentum("p", "N s", 0.0, "the momentum")
    bath = model.subsystem("bath", ...)                                   # (U_a, S_a) and tau_a
    v = bath.invariant("p", p, scale=...)                                 # a mechanical invariant
    bath.internal_energy(v**2/(2*m) + ..., bath.entropy)                  # U_a(x, s)
    model.mechanical_energy = k*q**2/2
    model.canonical_pair(q, p)                                            # L0
    model.friction(p, p, ...)                                             # K0 entries, K0(z, partials)

Why a SymPy module: the paper states a model as potentials and matrices, and SymPy keeps them
as formulas the generator can differentiate, invert (U(S) to U(theta) and U(u)) and share
subexpressions of (sympy.cse), while Python gives loops for N repeated elements (a chain's
springs) without a language of our own. The generator, not the description, knows the
Fortran interface (src/structure/model_interface.f90)."""
from dataclasses import dataclass, field

import sympy as sp

THERMO_VARIABLES = ("entropy", "temperature", "internal_energy")   # thermo_variable_kinds' order
TAU_PREFIX = {"entropy": "s", "temperature": "theta", "internal_energy": "u"}
# The symbols a subsystem's `inverses` are written in: s(x, theta) and s(x, u) for internal_energy(U, s);
# theta(x, s) and theta(x, u) for free_energy(psi, theta).
TEMPERATURE = sp.Symbol("theta", positive=True)
ENERGY_LEVEL = sp.Symbol("energy_level", positive=True)
ENTROPY_LEVEL = sp.Symbol("entropy_level", real=True)


class DescriptionError(ValueError):
    """A description that the generator cannot turn into a model: the message names what."""


@dataclass
class Parameter:
    """A parameter of the model's &model group."""
    symbol: sp.Symbol
    units: str
    default: float
    minimum: float = None
    exclusive: bool = False
    maximum: float = None
    meaning: str = ""

    @property
    def name(self):
        return self.symbol.name


@dataclass
class StateColumn:
    """A mechanical column of z (a position or a momentum) and its &initial field."""
    symbol: sp.Symbol
    units: str
    initial: float
    meaning: str
    kind: str                      # 'position' or 'momentum'
    minimum: float = None
    exclusive: bool = False        # both bounds exclusive (the maximum's equality is left to the domain checks)
    maximum: float = None
    dataset: bool = True           # a momentum: a column of the output's momentum dataset

    @property
    def name(self):
        return self.symbol.name


@dataclass
class Invariant:
    """A mechanical invariant of a subsystem: its symbol in U_a and S_a, its expression in z (at
    most quadratic) and its typical size for the discrete gradients' metric."""
    symbol: sp.Symbol
    expression: sp.Expr
    scale: sp.Expr
    positive: bool = False         # the potentials' domain: x > 0 (domain_nonpositive_length otherwise)


@dataclass
class Subsystem:
    """A thermodynamic subsystem: its potentials (U_a, S_a) in its invariants and its variable."""
    name: str
    meaning: str
    initial_temperature: float            # None: the model's initial_thermal_field gives its state
    tau_scales: dict                      # thermodynamic variable -> the tau column's typical size
    invariants: list = field(default_factory=list)
    entropy: sp.Symbol = None             # s, for internal_energy(U, s)
    temperature_symbol: sp.Symbol = None  # theta, for free_energy(psi, theta)
    energy_of_entropy: sp.Expr = None     # U_a(x, s)
    free_energy_of_temperature: sp.Expr = None  # psi_a(x, theta)
    energy_and_entropy_of_temperature: tuple = None  # (u_a(x, theta), s_a(x, theta)) of a free energy u - theta s
    inverses: dict = field(default_factory=dict)  # variable -> s or theta in TEMPERATURE, ENERGY_LEVEL or
    #                                               ENTROPY_LEVEL: where SymPy cannot solve, or to state its form
    temperature: sp.Symbol = None         # Theta_a of eq. (2), for K0
    partial_symbols: dict = field(default_factory=dict)  # ('U' or 'S', invariant name) -> Symbol
    label: str = ""                       # its name in messages and the output (default: name)
    thermal: bool = True                  # False: no thermodynamic variable (mechanical_subsystem)
    stored_energy_of_invariants: sp.Expr = None  # U_a = W(x) of a mechanical subsystem (S_a = 0)

    def invariant(self, name, expression, scale, positive=False):
        """A mechanical invariant x_i(z) of this subsystem, returned as the symbol U_a and S_a take;
        positive: U_a and S_a are defined for x_i > 0 only (a volume, a length), which the generated
        potentials check first (domain_nonpositive_length). The symbol stays real, so that SymPy keeps
        exp(a log x) as written rather than as a power x**a (a pow costs more than the exp it replaces)."""
        symbol = sp.Symbol(name, real=True)
        if any(existing.symbol.name == name for existing in self.invariants):
            raise DescriptionError(f"subsystem {self.name}: invariant {name} twice")
        self.invariants.append(Invariant(symbol, sp.sympify(expression), sp.sympify(scale), positive))
        return symbol

    def internal_energy(self, energy, entropy):
        """U_a(x, s) with s = `entropy` (the entropy form; S_a = s)."""
        self.energy_of_entropy, self.entropy = sp.sympify(energy), entropy

    def free_energy(self, psi, theta):
        """psi_a(x, theta) (the Helmholtz form; S_a = -dpsi/dtheta, U_a = psi + theta S_a)."""
        self.free_energy_of_temperature, self.temperature_symbol = sp.sympify(psi), theta

    def energy_and_entropy(self, energy, entropy, theta):
        """u_a(x, theta) and s_a(x, theta), the internal energy and entropy of the free energy psi_a = u_a - theta s_a
        as the paper's closed forms give them (docs/formulation.md section 3), in the temperature form: the
        generator checks du/dtheta = theta ds/dtheta (psi's s = -dpsi/dtheta) and takes the other variables'
        forms from `inverses` ('entropy': theta(x, ENTROPY_LEVEL), 'internal_energy': theta(x, ENERGY_LEVEL)) by
        substitution alone, without simplifying (which would fold logs and powers into costlier, less
        accurate forms)."""
        self.energy_and_entropy_of_temperature, self.temperature_symbol = (sp.sympify(energy), sp.sympify(entropy)), theta

    def stored_energy(self, energy):
        """U_a = W(x) of a mechanical subsystem's invariants alone (S_a = 0: an elastic spring's stored energy)."""
        if self.thermal:
            raise DescriptionError(f"subsystem {self.name}: stored_energy is a mechanical subsystem's (it has a "
                                   "thermodynamic variable: give U and S)")
        self.stored_energy_of_invariants = sp.sympify(energy)

    def partial(self, potential, invariant):
        """The symbol of d potential_a / d invariant ('U' or 'S'; an invariant's name, or 'tau'),
        for K0: exact at a state, a discrete gradient between two."""
        if potential not in ("U", "S"):
            raise DescriptionError(f"subsystem {self.name}: potential {potential!r} is not 'U' or 'S'")
        return self.partial_symbols.setdefault((potential, invariant),
                                               sp.Symbol(f"d{potential.lower()}_{self.name}_d{invariant}", real=True))


class ModelDescription:
    """What a model is, in the paper's terms (module docstring)."""

    def __init__(self, name, title, reference, energy_units="J", entropy_units="J/K", temperature_units="K"):
        self.name, self.title, self.reference = name, title, reference
        self.energy_units, self.entropy_units, self.temperature_units = energy_units, entropy_units, temperature_units
        self.parameters, self.columns, self.subsystems = [], [], []
        self.mechanical_energy = sp.Integer(0)
        self.poisson_entries = {}      # (row symbol, column symbol) -> L0 entry
        self.friction_entries = {}     # (row symbol, column symbol) -> K0 entry (symmetric)
        self.conserved = []            # momentum symbols that are first integrals
        self.theta_r = None            # the default Lyapunov reference temperature
        self.field_text = ""           # the written-out field, in words, for the module header
        self.words = {}                # model_words' temperature, energy, entropy, metric_scales (else generic)
        self.thermal_field = None      # initial_thermal_field's (variable, name, values, meaning)
        self.initial_domain = ""       # what &initial allows beyond its fields' bounds, for the refusal
        self.scene = True              # False: the generator writes no scene (a hand-written one builds the model)
        self.continuous_field = False  # True: continuous_field composed in z, not through the partials (faster)
        self.differences = False       # True: the potentials' U(b) - U(a), S(b) - S(a) free of cancellation
        self.rounding_scales = False   # True: the potentials' rounding scales from their terms (rounding_scale), not |U|
        self.angular_momentum_pairs = None  # [(q vector, p vector)] of J = sum q_a x p_a, and gravity's components
        self.gravity = None
        # An element's potentials alone (potential_only): another model's own code assembles it, as the spring
        # chain's does its springs; the generator writes NAME_potential.f90 and nothing else (element_module).
        self.potential_only = False
        self.stored_energies = []      # potential_only: (Subsystem, U) of kinds without a thermodynamic variable, S = 0
        self.temperature_functions = []  # potential_only: (name, meaning, f(TEMPERATURE)) with d(1/f)/dtheta

    def describe(self, **words):
        """How the output and the messages describe the model (model_interface's model_words):
        temperature, energy, entropy, metric_scales."""
        unknown = set(words) - {"temperature", "energy", "entropy", "metric_scales"}
        if unknown:
            raise DescriptionError(f"model {self.name}: describe() knows no {sorted(unknown)}")
        self.words.update(words)

    # ---------------------------------------------------------------- the parts
    def parameter(self, name, units, default, meaning="", minimum=None, exclusive=False, maximum=None,
                  positive=False):
        """A real parameter of &model, returned as its symbol (positive: a symbol SymPy may assume > 0)."""
        self._new_name(name)
        symbol = sp.Symbol(name, positive=True) if positive else sp.Symbol(name, real=True)
        self.parameters.append(Parameter(symbol, units, float(default), minimum, exclusive, maximum, meaning))
        return symbol

    def position(self, name, units, initial, meaning, minimum=None, exclusive=False, maximum=None):
        """A position column of z, returned as its symbol; &initial reads its value within the bounds."""
        return self._column(StateColumn(sp.Symbol(name, real=True), units, float(initial), meaning, "position",
                                        minimum, exclusive, maximum))

    def momentum(self, name, units, initial, meaning, conserved=False, dataset=True):
        """A momentum column of z (`conserved`: a first integral; dataset=False: not a column of the
        output's momentum dataset, as for a model that reports no momenta)."""
        if conserved and not dataset:
            raise DescriptionError(f"model {self.name}: momentum {name} conserved but not in the momentum dataset")
        symbol = self._column(StateColumn(sp.Symbol(name, real=True), units, float(initial), meaning, "momentum",
                                          dataset=dataset))
        if conserved:
            self.conserved.append(symbol)
        return symbol

    def angular_momentum(self, pairs, gravity):
        """The momenta J = sum_a q_a x p_a (J_x, J_y, J_z) of the (position, momentum) vector pairs, three
        columns each; its components conserved under the parameters' gravity (g_x, g_y, g_z) are
        angular_momentum_components' (docs/formulation.md section 2). In the plane (vectors of 2
        components, gravity (g_x, g_y)) J is the one component about the normal, conserved without
        gravity (docs/formulation.md section 9)."""
        if self.conserved or any(c.dataset for c in self.columns if c.kind == "momentum"):
            raise DescriptionError(f"model {self.name}: angular_momentum with momenta of the momentum dataset")
        dimension = len(gravity)
        if dimension not in (2, 3) or any(len(q) != dimension or len(p) != dimension for q, p in pairs):
            raise DescriptionError(f"model {self.name}: angular_momentum takes vectors of 3 components (or 2, planar)")
        self.angular_momentum_pairs, self.gravity = [(list(q), list(p)) for q, p in pairs], list(gravity)

    def initial_thermal_field(self, variable, name, values, meaning):
        """&initial gives the subsystems' thermodynamic state as one field `name` of a value per
        subsystem in `variable` (one of THERMO_VARIABLES), instead of a temperature each."""
        if variable not in THERMO_VARIABLES:
            raise DescriptionError(f"model {self.name}: initial_thermal_field's variable {variable!r} is not one of "
                                   f"{THERMO_VARIABLES}")
        self.thermal_field = (variable, name, [float(v) for v in values], meaning)

    def subsystem(self, name, meaning, initial_temperature, tau_scales, label=""):
        """A thermodynamic subsystem with its own variable tau_a (a column of z, last of its
        invariants); tau_scales: {variable: typical size of tau} for the metric; `name` names its
        symbols and its thermodynamic column (s_NAME, ...), `label` (default: name) the output's and
        messages' words for it; initial_temperature None with an initial_thermal_field."""
        self._new_name(name)
        missing = set(THERMO_VARIABLES) - set(tau_scales)
        if missing:
            raise DescriptionError(f"subsystem {name}: tau_scales lacks {sorted(missing)}")
        part = Subsystem(name, meaning, None if initial_temperature is None else float(initial_temperature),
                         {k: sp.sympify(v) for k, v in tau_scales.items()}, label=label or name)
        part.temperature = sp.Symbol(f"theta_{name}", positive=True)
        self.subsystems.append(part)
        return part

    def mechanical_subsystem(self, name, meaning, label=""):
        """A subsystem without a thermodynamic variable (an elastic spring): its potentials are U_a = W(x) of its
        mechanical invariants (`stored_energy`) and S_a = 0; no tau column, no temperature, no K0 entry. A model's
        subsystems are all thermal or all mechanical (model_interface's temperature_count)."""
        self._new_name(name)
        part = Subsystem(name, meaning, None, {}, label=label or name, thermal=False)
        self.subsystems.append(part)
        return part

    def canonical_pair(self, position, momentum):
        """L0 canonical in (position, momentum): dq/dt = dE/dp, dp/dt = -dE/dq (eq. (8))."""
        self.poisson_entries[(position, momentum)] = sp.Integer(1)
        self.poisson_entries[(momentum, position)] = sp.Integer(-1)

    def friction(self, row, column, entry):
        """K0's entry (row, column) and its mirror: rows and columns are state symbols or a
        subsystem's `tau(part)`; entries may use the parameters, the subsystems' temperatures and
        partials, and the mechanical columns of z (K0(z, partials): a drag on the velocity p/m), not
        a `tau` column (s, theta or u by the variable). A scheme evaluates K0 where it evaluates the
        field: at z_mid with the step's discrete temperatures (docs/formulation.md section 5). For
        K grad E = 0, K0 must annihilate M_E^T grad E = (grad of the mechanical energy, 1 on the tau
        rows): a friction on a momentum p whose energy is mechanical needs its (p, tau) and
        (tau, tau) entries too (docs/formulation.md section 11)."""
        self.friction_entries[(row, column)] = sp.sympify(entry)
        self.friction_entries[(column, row)] = sp.sympify(entry)

    @staticmethod
    def tau(part):
        """The symbol of subsystem `part`'s thermodynamic column, for K0's rows and columns."""
        return sp.Symbol(f"tau_{part.name}", real=True)

    # ---------------------------------------------------------------- an element (potential_only)
    def stored_energy(self, name, meaning, invariants, energy):
        """potential_only: a kind of the element without a thermodynamic variable (an elastic spring): U = `energy`
        of the positive `invariants` [(name, metric scale)], S = 0. The element's kinds are numbered from 1, the
        stored energies first, then the subsystems, each in the order stated."""
        if not self.potential_only:
            raise DescriptionError(f"model {self.name}: stored_energy is for a potential_only element")
        part = Subsystem(name, meaning, None, {}, label=name)
        for invariant, scale in invariants:
            part.invariant(invariant, sp.Symbol(invariant, real=True), scale, positive=True)
        self.stored_energies.append((part, sp.sympify(energy)))

    def temperature_function(self, name, meaning, value):
        """potential_only: a function of the temperature (in the symbol TEMPERATURE), written as NAME(theta, value,
        dinverse_dtheta) with d(1/value)/dtheta (a rate value^-1 needs it), as eq. (17)'s viscosity."""
        if not self.potential_only:
            raise DescriptionError(f"model {self.name}: temperature_function is for a potential_only element")
        self.temperature_functions.append((name, meaning, sp.sympify(value)))

    # ---------------------------------------------------------------- helpers
    def _new_name(self, name):
        taken = {p.name for p in self.parameters} | {c.name for c in self.columns} | {s.name for s in self.subsystems}
        if name in taken:
            raise DescriptionError(f"model {self.name}: the name {name} twice")

    def _column(self, column):
        self._new_name(column.name)
        self.columns.append(column)
        return column.symbol


# ---------------------------------------------------------------------------------- a chain of repeated elements

class ElementView:
    """What an element's builders see in `dimension` components: point a+k's position x(k) and momentum p(k)
    (column vectors), spring a+s's temperature theta(s) and viscosity(s) = eta(Theta_{a+s}), and parameters."""

    def __init__(self, dimension, shift=0):
        self.dimension, self.shift = dimension, shift

    def x(self, k):
        return sp.Matrix([sp.Symbol(f"x{k + self.shift}_{c}", real=True) for c in range(1, self.dimension + 1)])

    def p(self, k):
        return sp.Matrix([sp.Symbol(f"p{k + self.shift}_{c}", real=True) for c in range(1, self.dimension + 1)])

    def theta(self, s):
        return sp.Symbol(f"theta{s + self.shift}", positive=True)

    def viscosity(self, s):
        return VISCOSITY(self.theta(s))

    @staticmethod
    def parameter(name):
        return sp.Symbol(name, positive=True)

    def vector(self, name):
        return sp.Matrix([sp.Symbol(f"{name}({c})", real=True) for c in range(1, self.dimension + 1)])


VISCOSITY = sp.Function("viscosity")     # eta(Theta) of the repeated spring (its element's temperature_function)


@dataclass
class ChainElement:
    """One kind of element repeated along the chain: the points (offsets from a) and springs it touches, the rows of
    the field it fills, its energy, L0 (canonical on its points' (x, p)) and K0 entries between its springs'
    gamma and tau."""
    name: str
    points: tuple
    springs: tuple
    rows: tuple
    parameters: tuple
    energy: object = None          # ElementView -> expression
    canonical: bool = False
    friction: object = None        # ElementView -> {((slot, s), (slot, s')): entry}, slot 'gamma' or 'tau'


class ChainDescription:
    """A model made of N repeated elements with neighbour coupling (issue 42): point a holds a mass (x_a, p_a) and
    spring a's own unknowns (gamma_a, tau_a); every element touches points and springs at fixed offsets from a, so
    the field is a sum of small blocks and its Jacobian is banded. The generator writes each element's block (its
    part of f = L DE + K DS, eq. (8), and its derivatives in its unknowns and in its springs' partials) for every
    dimension and rung; the loop over the elements stays in the model's Fortran."""

    def __init__(self, name, title, reference, spring, rungs, dimensions=(1, 2, 3)):
        self.name, self.title, self.reference = name, title, reference
        self.spring, self.rungs, self.dimensions = spring, dict(rungs), tuple(dimensions)
        self.elements = []
        self.spring_invariant = None
        self.potential_only, self.scene, self.parameters = False, False, []

    def invariant(self, build):
        """Spring a's invariant C_a in the positions of the points around a (build(view) -> expression)."""
        self.spring_invariant = build

    def element(self, name, points, springs, rows, parameters=(), energy=None, canonical=False, friction=None):
        """A repeated element (ChainElement); `parameters` name its kernel's scalar and vector data in order."""
        if any(e.name == name for e in self.elements):
            raise DescriptionError(f"chain {self.name}: element {name} twice")
        unknown = set(rows) - {"x", "p", "gamma", "tau"}
        if unknown:
            raise DescriptionError(f"chain {self.name}: element {name} fills rows {sorted(unknown)}; allowed: x, p, "
                                   "gamma, tau")
        self.elements.append(ChainElement(name, tuple(points), tuple(springs), tuple(rows), tuple(parameters), energy,
                                          canonical, friction))
