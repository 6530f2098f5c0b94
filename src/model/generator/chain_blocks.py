"""NAME_blocks.f90 of a ChainDescription (model_description.py): for each repeated element, dimension and rung, a
pure kernel of the element's part of f = M_S^T L0 M_S DE + M_E^T K0 M_E DS (eq. (8), docs/formulation.md section 4)
in its local slots, with df/d(new slots) and df/d(its springs' partials), and one public NAME_block per element that
picks the kernel. The slots are the layout's (spring_chain_layout): the element's points in order, each x (and p if
L0 is canonical on them), then each spring's gamma and tau. A spring's partials come from spring_chain_partials
(partials(i, k): D_i of U (k = 1) or S (k = 2) in invariant i; dpartials(i, k, j) their derivatives in the spring's
own slot j; theta = D_tau U/D_tau S; weight: d(evaluation point)/d(new slot))."""
import sympy as sp

from model_description import DescriptionError, ElementView, VISCOSITY
from generate_model import INDENT, assignments, header, tidy, wrap

PARTS = {1: ("part",), 2: ("part_a", "part_b")}


def part_name(element, s):
    return PARTS[len(element.springs)][element.springs.index(s)]


class ElementField:
    """One element in `dimension` components on rung n: its slots, its field rows and their derivatives."""

    def __init__(self, chain, element, dimension, n):
        self.chain, self.element, self.d, self.n = chain, element, dimension, n
        self.view = ElementView(dimension)
        names = chain.rungs.get(n, ())
        self.thermal = "tau" in names
        self.slots, self.kind = [], {}
        for k in element.points:
            for vector, kind in ((self.view.x(k), "x"), (self.view.p(k), "p")):
                if kind == "p" and not element.canonical:
                    continue
                for symbol in vector:
                    self.slots.append(symbol)
                    self.kind[symbol] = kind
        for s in element.springs:
            for name in names[1:]:
                symbol = self.own(name, s)
                self.slots.append(symbol)
                self.kind[symbol] = name
        self.index = {symbol: j for j, symbol in enumerate(self.slots)}
        # A spring's invariants in the element's slots, and the points its invariant joins (its own slots' order).
        probe = chain.spring_invariant(ElementView(dimension))
        self.spring_points = sorted({int(symbol.name[1:].split("_")[0]) for symbol in probe.free_symbols})
        self.invariants = {s: [chain.spring_invariant(ElementView(dimension, shift=s))] +
                           [self.own(name, s) for name in names[1:]] for s in element.springs}
        for s, invariants in self.invariants.items():
            missing = invariants[0].free_symbols - set(self.slots)
            if missing:
                raise DescriptionError(f"chain {chain.name}: element {element.name}'s spring {s} reaches "
                                       f"{sorted(map(str, missing))}, not points of the element")

    @staticmethod
    def own(name, s):
        return sp.Symbol(f"{name}{s}", real=True)

    def partial(self, i, k, s):
        """D_i of potential k (1: U, 2: S) of spring s, as the Fortran reference."""
        return sp.Symbol(f"{part_name(self.element, s)}%partials({i}, {k})", real=True)

    def theta(self, s):
        return sp.Symbol(f"{part_name(self.element, s)}%theta", positive=True)

    def eta(self, s):
        return sp.Symbol("eta", positive=True)

    def gradient(self, s, k):
        """grad over the slots of potential k of spring s, through its invariants."""
        return sp.Matrix([sum(self.partial(i + 1, k, s)*sp.diff(x, z) for i, x in enumerate(self.invariants[s]))
                          for z in self.slots])

    def mielke_transpose(self, k):
        """M^T of eq. (7) for potential k over the element's springs (identity without a tau)."""
        mt = sp.eye(len(self.slots))
        if not self.thermal:
            return mt
        for s in self.element.springs:
            column = self.index[self.own("tau", s)]
            d_tau = self.partial(self.n, k, s)
            grad = self.gradient(s, k)
            for j, z in enumerate(self.slots):
                if self.kind[z] != "tau":
                    mt[j, column] = -grad[j]/d_tau
            mt[column, column] = 1/d_tau
        return mt

    def field(self):
        if not hasattr(self, "_rows"):
            self._rows = self.compose()
        return self._rows

    def compose(self):
        """The rows the element fills: [(slot index, f)], in the partials, the temperatures, eta and the slots."""
        m = len(self.slots)
        energy = self.element.energy(self.view) if self.element.energy else sp.Integer(0)
        grad_e = sp.Matrix([sp.diff(energy, z) for z in self.slots])
        grad_s = sp.zeros(m, 1)
        for s in self.element.springs:
            grad_e += self.gradient(s, 1)
            if self.thermal:
                grad_s += self.gradient(s, 2)
        l0, k0 = sp.zeros(m, m), sp.zeros(m, m)
        if self.element.canonical:
            for k in self.element.points:
                for x, p in zip(self.view.x(k), self.view.p(k)):
                    l0[self.index[x], self.index[p]], l0[self.index[p], self.index[x]] = 1, -1
        if self.element.friction and self.thermal:
            for ((row, s), (column, t)), entry in self.element.friction(self.view).items():
                a, b = self.own(row, s), self.own(column, t)
                if a in self.index and b in self.index:
                    k0[self.index[a], self.index[b]] += entry
        mt_s, mt_e = self.mielke_transpose(2), self.mielke_transpose(1)
        f = mt_s.T*(l0*(mt_s*grad_e)) + mt_e.T*(k0*(mt_e*grad_s))
        # Theta_s as the spring's theta, eta(Theta) as eta, and D_tau U = Theta D_tau S: theta is a coordinate.
        replace = {}
        for s in self.element.springs:
            replace[self.view.theta(s)] = self.theta(s)
            if self.thermal:
                replace[self.partial(self.n, 1, s)] = self.theta(s)*self.partial(self.n, 2, s)
        rows = []
        for j, z in enumerate(self.slots):
            if self.kind[z] in self.element.rows:
                value = f[j].xreplace(replace)
                value = value.replace(lambda e: isinstance(e, sp.Function) and e.func == VISCOSITY,
                                      lambda e: self.eta(0))
                # The product of the matrices or its one fraction, whichever costs fewer operations: (Theta D_gamma S
                # - D_gamma U)/eta rather than Theta (D_gamma S - D_gamma U/Theta)/eta.
                rows.append((j, min((value, sp.together(value)), key=sp.count_ops)))
        return rows

    def partial_coordinates(self):
        """(i, k, s) of every partial the element's springs have."""
        count = 1 if not self.thermal else self.n
        return [(i, k, s) for s in self.element.springs for i in range(1, count + 1) for k in (1, 2)
                if self.thermal or k == 1]

    def total_partial(self, value, i, k, s):
        """d value/d partials(i, k) of spring s, through theta = D_tau U/D_tau S and eta(theta)."""
        dinverse_eta = sp.Symbol("dinverse_eta", real=True)
        if self.thermal and i == self.n:
            by_theta = sp.diff(value, self.theta(s)) + sp.diff(value, self.eta(s))*(-self.eta(s)**2*dinverse_eta)
            if k == 1:
                return by_theta/self.partial(self.n, 2, s)
            return sp.diff(value, self.partial(i, k, s)) - by_theta*self.theta(s)/self.partial(self.n, 2, s)
        return sp.diff(value, self.partial(i, k, s))

    def spring_slot(self, s, z):
        """Spring s's own slot number (1-based) of element slot z, 0 if its invariants do not reach z."""
        own = []
        for k in self.spring_points:
            own += list(ElementView(self.d, shift=s).x(k)) + list(ElementView(self.d, shift=s).p(k))
        own += self.invariants[s][1:]
        reached = set().union(*(x.free_symbols for x in self.invariants[s]))
        return own.index(z) + 1 if z in reached else 0


def kernel_name(element, d, n):
    return f"{element.name}_block_{d}d" + (f"_rung{n}" if element.springs else "")


def arguments(element, field):
    """The kernel's dummy arguments and declarations: data, slots' values and parts, outputs."""
    uses_eta = any(field.eta(0) in value.free_symbols for _, value in field.field())
    if uses_eta and len(element.springs) != 1:
        raise DescriptionError(f"element {element.name}: viscosity(s) in an element of {len(element.springs)} springs; "
                               "a kernel calls its one spring's viscosity")
    names, lines = [], []
    energy = element.energy(field.view) if element.energy else sp.Integer(0)
    vectors = [name for name in element.parameters if sp.Symbol(f"{name}(1)", real=True) in energy.free_symbols]
    scalars = [name for name in element.parameters if name not in vectors]
    if element.springs:
        if uses_eta:
            names.append("spring")
            lines.append("type(chain_spring), intent(in) :: spring")
        parts = list(PARTS[len(element.springs)])
        direct = any(field.kind[z] in ("x", "p") for _, value in field.field() for z in value.free_symbols
                     if z in field.index)
        if len(element.springs) == 1:
            names += parts + (["old", "new"] if direct else []) + list(element.parameters)
        else:
            names += list(element.parameters) + parts
        lines.append(f"type(spring_partials), intent(in) :: {', '.join(parts)}")
        if direct:
            lines.append("real(real64), intent(in) :: old(:), new(:)")
    else:
        names += list(element.parameters) + ["p_old", "p_new", "weight"]
        lines.append("real(real64), intent(in) :: p_old(:), p_new(:), weight")
    for name in scalars:
        lines.append(f"real(real64), intent(in) :: {name}")
    for name in vectors:
        lines.append(f"real(real64), intent(in) :: {name}(:)")
    extra = {1: "df_dpartials", 2: "df_dtau_partials"}.get(len(element.springs))
    names += ["f", "df"] + ([extra] if extra else [])
    lines.append("real(real64), intent(out) :: f(:)")
    lines.append("real(real64), intent(out), optional :: df(:, :)" + (f", {extra}(:, :, :)" if extra else ""))
    return names, lines, uses_eta


def kernel(chain, element, d, n):
    """One pure subroutine: the element's block in d dimensions on rung n."""
    field = ElementField(chain, element, d, n)
    rows = field.field()
    names, declarations, uses_eta = arguments(element, field)
    name = kernel_name(element, d, n)
    used = set().union(*(value.free_symbols for _, value in rows)) if rows else set()
    direct_slots = [z for z in field.slots if z in used]
    if not element.springs and any(field.kind[z] != "p" for z in direct_slots):
        raise DescriptionError(f"chain {chain.name}: element {element.name} reads its positions (its kernel gets "
                               "its momenta)")
    # The values at the evaluation point: (1 - w) old + w new.
    values = {z: sp.Symbol(f"z_{field.index[z] + 1}", real=True) for z in direct_slots}
    rows = [(j, value.xreplace(values)) for j, value in rows]
    weight = "weight" if not element.springs else "part%weight"
    unpack = []
    for z in direct_slots:
        j = field.index[z] + 1
        source = j - d if not element.springs else j     # a mass's arrays hold its momenta
        old, new = ("p_old", "p_new") if not element.springs else ("old", "new")
        unpack.append(f"z_{j} = (1.0_real64 - {weight})*{old}({source}) + {weight}*{new}({source})")
    targets_f = [f"f({j + 1})" for j, _ in rows]
    values_f = [value for _, value in rows]
    # Derivatives: in the partials (through theta and eta), and direct in the slots' evaluation values.
    coordinates = field.partial_coordinates()
    by_partial = [[field.total_partial(value, i, k, s) for (i, k, s) in coordinates] for _, value in rows]
    direct = [[sp.diff(value, values[z]) if z in values else sp.Integer(0) for z in field.slots] for _, value in rows]
    derivative_targets, derivative_values, slot_of = [], [], {}
    for r, (j, _) in enumerate(rows):
        for c, (i, k, s) in enumerate(coordinates):
            if by_partial[r][c] != 0:
                slot_of[("p", r, c)] = len(derivative_values) + 1
                derivative_targets.append(f"g({len(derivative_values) + 1})")
                derivative_values.append(by_partial[r][c])
        for c, z in enumerate(field.slots):
            if direct[r][c] != 0:
                slot_of[("z", r, c)] = len(derivative_values) + 1
                derivative_targets.append(f"g({len(derivative_values) + 1})")
                derivative_values.append(direct[r][c])
    # The Jacobian's entries: weight * direct + sum over partials of g * dpartials.
    jacobian = []
    for r, (j, _) in enumerate(rows):
        for c, z in enumerate(field.slots):
            terms = []
            if ("z", r, c) in slot_of:
                terms.append(f"{weight}*g({slot_of[('z', r, c)]})")
            for q, (i, k, s) in enumerate(coordinates):
                own = field.spring_slot(s, z)
                if own and ("p", r, q) in slot_of:
                    terms.append(f"g({slot_of[('p', r, q)]})*{part_name(element, s)}%dpartials({i}, {k}, {own})")
            if terms:
                jacobian.append(wrap(f"df({j + 1}, {c + 1}) = " + " + ".join(terms), 2))
    extra = {1: "df_dpartials", 2: "df_dtau_partials"}.get(len(element.springs))
    by_partial_out = []
    for r, (j, _) in enumerate(rows):
        for c, (i, k, s) in enumerate(coordinates):
            if ("p", r, c) not in slot_of:
                continue
            if len(element.springs) == 1:
                by_partial_out.append(f"{extra}({j + 1}, {i}, {k}) = g({slot_of[('p', r, c)]})")
            elif i == field.n:
                by_partial_out.append(f"{extra}({j + 1}, {k}, {element.springs.index(s) + 1}) = "
                                      f"g({slot_of[('p', r, c)]})")
            else:
                raise DescriptionError(f"chain {chain.name}: element {element.name} reads a partial other than "
                                       "D_tau of its two springs")
    temporaries_f, temporaries_all = [0], [0]
    lines_f = assignments(targets_f, values_f, 3, temporaries_f)
    lines_all = assignments(targets_f + derivative_targets, values_f + derivative_values, 2, temporaries_all)
    count = max(temporaries_f[0], temporaries_all[0])
    local = [f"z_{field.index[z] + 1}" for z in direct_slots] + (["eta", "dinverse_eta"] if uses_eta else []) + \
        [f"t_{i}" for i in range(1, count + 1)]
    out = [f"  !> {element.name.capitalize()} block in {d} dimension{'s' if d > 1 else ''}"
           + (f" on rung {n}" if element.springs else "") + ".",
           f"  pure subroutine {name}({', '.join(names)})"]
    out += [INDENT*2 + line for line in declarations]
    if local:
        out.append(wrap("real(real64) :: " + ", ".join(local), 2))
    if derivative_values:
        out.append(INDENT*2 + f"real(real64) :: g({len(derivative_values)})")
    out.append("")
    out += [INDENT*2 + line for line in unpack]
    if uses_eta:
        out.append(INDENT*2 + "call spring%viscosity(part%theta, eta, dinverse_eta)")
    out.append(INDENT*2 + "f = 0.0_real64")
    present = "present(df)" + (f" .or. present({extra})" if extra else "")
    out.append(INDENT*2 + f"if (.not. ({present})) then")
    out += lines_f
    out.append(INDENT*3 + "return")
    out.append(INDENT*2 + "end if")
    out += lines_all
    if extra:
        out.append(INDENT*2 + f"if (present({extra})) then")
        out.append(INDENT*3 + f"{extra} = 0.0_real64")
        out += [INDENT*3 + line for line in by_partial_out]
        out.append(INDENT*2 + "end if")
    out.append(INDENT*2 + "if (.not. present(df)) return")
    out.append(INDENT*2 + "df = 0.0_real64")
    out += jacobian
    out.append(f"  end subroutine {name}")
    return "\n".join(out), names


def element_rungs(chain, element):
    """The rungs an element has a block on: a element that fills tau rows alone (a link) exists on thermal rungs."""
    if not element.springs:
        return [0]
    if set(element.rows) <= {"tau", "gamma"}:
        return [n for n in chain.rungs if "tau" in chain.rungs[n]]
    return list(chain.rungs)


def blocks_module(chain, source):
    """The text of NAME_blocks.f90."""
    if chain.spring_invariant is None:
        raise DescriptionError(f"chain {chain.name}: no spring invariant (model.invariant)")
    kernels, dispatchers, public = [], [], []
    for element in chain.elements:
        made = [(d, n, *kernel(chain, element, d, n)) for d in chain.dimensions for n in element_rungs(chain, element)]
        kernels += [text for _, _, text, _ in made]
        public.append(f"{element.name}_block")
        dispatchers.append(dispatch(chain, element, made))
    name = f"{chain.name}_blocks"
    what = f"The blocks of {chain.title} ({chain.reference}), one per repeated element:"
    text = f"""{header(chain, source, what)}
!> each element's part of f = L DE + K DS in its local slots (spring_chain_layout), with df/d(new slots) and
!> df/d(its springs' partials) (spring_chain_partials), in {', '.join(map(str, chain.dimensions))} dimensions on \
every rung. A step's residual
!> is (z_new - z_old)/dt - the sum of the blocks; spring_chain_step and spring_chain_dmda add them into banded rows.
module {name}
  use, intrinsic :: iso_fortran_env, only: real64
  use spring_chain_spring, only: chain_spring
  use spring_chain_partials, only: spring_partials
  implicit none (type, external)
  private
  public :: {', '.join(public)}

contains

{chr(10).join(d + chr(10) for d in dispatchers)}
{chr(10).join(k + chr(10) for k in kernels)}
end module {name}
"""
    return tidy(text)


def dispatch(chain, element, made):
    """The public NAME_block over the kernels `made` [(d, n, text, argument names)]: the kernel of the parts'
    dimension and rung (of its vector datum's size without a spring); its arguments are the widest kernel's."""
    widest = max(made, key=lambda m: len(m[3]))
    names = widest[3]
    declarations = arguments(element, ElementField(chain, element, widest[0], widest[1] or max(chain.rungs)))[1]
    lines = [f"  !> The {element.name} block: f on its local slots and optionally df/d(new slots)"
             + (", df/d(its springs' partials)." if element.springs else "."),
             f"  pure subroutine {element.name}_block({', '.join(names)})"]
    lines += [INDENT*2 + line for line in declarations]
    if element.springs:
        first = PARTS[len(element.springs)][0]
        lines += [INDENT*2 + "integer :: d, n", "", INDENT*2 + f"n = {first}%invariants",
                  INDENT*2 + f"d = count({first}%slots%x_left > 0)", INDENT*2 + "select case (10*d + n)"]
    else:
        energy = element.energy(ElementView(1))
        vector = [name for name in element.parameters if sp.Symbol(f"{name}(1)", real=True) in energy.free_symbols][0]
        lines += [INDENT*2 + "integer :: d", "", INDENT*2 + f"d = size({vector})", INDENT*2 + "select case (d)"]
    for d, n, _, own in made:
        lines.append(INDENT*2 + f"case ({10*d + n if element.springs else d})")
        lines.append(wrap(f"call {kernel_name(element, d, n)}({', '.join(own)})", 3))
    lines += [INDENT*2 + "case default", INDENT*3 + "f = 0.0_real64", INDENT*3 + "if (present(df)) df = 0.0_real64",
              INDENT*2 + "end select", f"  end subroutine {element.name}_block"]
    return "\n".join(lines)
