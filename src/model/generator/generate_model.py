"""Writes the Fortran of a model from its description (model_description.py's format): the
potentials (U_a, S_a) with gradients and Hessians in each thermodynamic variable, the model (a
`generic_model` extension: invariants, the written-out field f = L grad E + K grad S with df/dz
and df/dpartials, the mechanical energy, L0 and K0, momenta) and its scene (&model and &initial
as field tables). Common subexpressions are shared with sympy.cse.

  generate_model.py DESCRIPTION [--output FOLDER]   write NAME_potential.f90, NAME_model.f90 and
                                                    NAME_scene.f90 (default: the description's folder)
  generate_model.py DESCRIPTION --input-rows        print the description's rows of docs/input.md

Exit status 2 with a message naming the description and what is wrong if it cannot be generated.
The generated files are committed (a clean clone builds without SymPy); `make generate` runs this
for every src/model/*/description.py and tests/e2e/test_generated_models.py checks that doing so
changes no byte."""
import argparse
import functools
import importlib.util
import math
import re
import sys
from random import Random
from pathlib import Path

import sympy as sp
from sympy.printing.fortran import FCodePrinter

sys.path.insert(0, str(Path(__file__).resolve().parent))
from model_description import (THERMO_VARIABLES, TAU_PREFIX, TEMPERATURE, ENERGY_LEVEL, ENTROPY_LEVEL,  # noqa: E402
                               ChainDescription, DescriptionError)
from fortran_names import name_clashes  # noqa: E402

LINE_LENGTH = 120
INDENT = "  "


# ---------------------------------------------------------------------------------- printing

class Real64Printer(FCodePrinter):
    """SymPy's Fortran printer with real64 literals, names as given and the parameters as
    components of self%parameters."""

    def __init__(self):
        super().__init__({"standard": 2008, "source_format": "free", "name_mangling": False,
                          "user_functions": {"log1p": "log1p", "expm1": "expm1"}})
        self.parameter_names = set()
        self.constant_names = {}           # a folded constant's symbol name -> its index in self%constants
        self.owner = "self%parameters"

    def _print_Symbol(self, expr):
        if expr.name in self.constant_names:
            return f"self%constants({self.constant_names[expr.name]})"
        if expr.name in self.parameter_names:
            return f"{self.owner}%{expr.name}"
        return expr.name

    def _print_Float(self, expr):
        return f"{float(expr)!r}_real64"

    def _print_Rational(self, expr):
        if expr.q & (expr.q - 1) == 0:          # a power of 2: the decimal is exact
            return f"{float(expr)!r}_real64"
        return f"({int(expr.p)}.0_real64/{int(expr.q)}.0_real64)"

    def _print_Integer(self, expr):
        return f"{int(expr)}.0_real64"

    def _print_Pow(self, expr):
        if expr.exp == sp.S.Half:              # FCodePrinter's sqrt(6.0d0) of an integer is no real64 literal
            return f"sqrt({self._print(expr.base)})"
        if expr.exp.is_Integer:
            if expr.exp == -1:
                return f"1.0_real64/{self.parenthesize(expr.base, sp.printing.precedence.precedence(expr))}"
            base = self.parenthesize(expr.base, sp.printing.precedence.precedence(expr))
            if expr.exp < 0:
                return f"1.0_real64/{base}**{-int(expr.exp)}"
            return f"{base}**{int(expr.exp)}"
        return super()._print_Pow(expr)


PRINTER = Real64Printer()


def fortran(expr):
    """One expression as Fortran text."""
    return PRINTER._print(sp.sympify(expr))


def wrap(line, indent):
    """`line` at `indent` levels, continued with & before LINE_LENGTH at a blank, an operator (never inside
    `**`) or a comma outside character literals."""
    lead = INDENT*indent
    text, lines = lead + line, []
    while len(text) > LINE_LENGTH:
        quote, cut = None, 0
        for position, character in enumerate(text[:LINE_LENGTH - 2]):
            if quote:
                if character == quote:
                    quote = None
            elif character in "'\"":
                quote = character
            elif position > len(lead) + 20 and character in " *+-," and text[position - 1:position + 1] != "**":
                cut = position + (character == ",")
        if cut == 0:
            break
        lines.append(text[:cut].rstrip() + " &")
        text = lead + INDENT*2 + text[cut:].lstrip()
    return "\n".join(lines + [text])


def assignments(targets, expressions, indent, temporaries):
    """Fortran assignments of `expressions` to `targets` with their common subexpressions as
    temporaries t_1, t_2, ... (sympy.cse); records the count in temporaries[0]."""
    shared, reduced = sp.cse(list(expressions), symbols=sp.numbered_symbols("t_", start=1), order="none")
    temporaries[0] = max(temporaries[0], len(shared))
    lines = [wrap(f"{fortran(name)} = {fortran(value)}", indent) for name, value in shared]
    lines += [wrap(f"{target} = {fortran(value)}", indent) for target, value in zip(targets, reduced)]
    return lines


def shared_exponentials(positive, *groups):
    """Every exp(A) in the expression lists `groups` as an integer power of one symbol exp_k = exp(B_k) per family of
    arguments that are rational multiples of one another (A = n B_k): ([(exp_k, B_k)], groups rewritten), inner
    exponentials first. The entropy variables' Theta_a = theta_ref exp(A) and 1/Theta_a = exp(-A)/theta_ref, and the
    Hessians' second exp(A) that SymPy writes in another form, cost one exp then, not one each. `positive` (symbols)
    are known > 0 when the ratios are compared."""
    assume = {x: sp.Dummy(x.name, positive=True) for x in positive}
    atoms = set()
    for group in groups:
        for e in group:
            atoms |= sp.sympify(e).atoms(sp.exp)
    families = []                                  # [argument of the first member, [(atom, ratio to it)]]
    for atom in sorted(atoms, key=lambda e: (sp.count_ops(e), sp.default_sort_key(e))):
        argument = atom.args[0].xreplace(assume)
        for family in families:
            ratio = sp.cancel(argument/family[0])
            if ratio.is_Rational and ratio != 0:
                family[1].append((atom, ratio))
                break
        else:
            families.append([argument, [(atom, sp.Integer(1))]])
    replacement, definitions = {}, []
    for k, (_, members) in enumerate(families):
        ratios = [ratio for _, ratio in members]
        unit = sp.Rational(functools.reduce(math.gcd, (int(r.p) for r in ratios)),
                           functools.reduce(math.lcm, (int(r.q) for r in ratios)))
        if sum(1 for r in ratios if r < 0) > sum(1 for r in ratios if r > 0):
            unit = -unit                           # most powers positive: a division for the rest
        symbol = sp.Symbol(f"exp_{k + 1}", real=True)
        definitions.append((symbol, unit*members[0][0].args[0]))
        for atom, ratio in members:
            replacement[atom] = symbol**int(ratio/unit)
    # Inner exponentials inside the definitions' arguments (an exp of a temperature) become their symbols too.
    definitions = [(symbol, argument.xreplace(replacement)) for symbol, argument in definitions]
    return definitions, [[sp.sympify(e).xreplace(replacement) for e in group] for group in groups]


def straight_line(targets, expressions, indent, temporaries, exponentials=(), refold=lambda e: e, early_targets=True):
    """Like `assignments`, with the exponentials of shared_exponentials (exp_k = exp(B_k)) computed where first
    needed, each after the check that B_k <= max_exponent (domain_overflow), and only the temporaries the targets
    need, numbered t_1, t_2, ... in the order they are written. early_targets=False writes every target after the
    calls (field_values: its targets without a call are then not kept, spilled, across the calls for the
    finiteness sum)."""
    exponentials = list(exponentials)
    shared, reduced = sp.cse([argument for _, argument in exponentials] + list(expressions),
                             symbols=sp.numbered_symbols("shared_", start=1), order="none")
    definitions = {name: value for name, value in shared}
    definitions.update({symbol: ("exp", argument) for (symbol, _), argument
                        in zip(exponentials, reduced[:len(exponentials)])})
    order = [name for name, _ in shared] + [symbol for symbol, _ in exponentials]
    position = {name: k for k, name in enumerate(order)}
    written, sequence = set(), []

    def needs(value):
        return sorted((x for x in sp.sympify(value).free_symbols if x in definitions), key=position.get)

    def write(name):
        if name in written:
            return
        written.add(name)
        value = definitions[name]
        for dependency in needs(value[1] if isinstance(value, tuple) else value):
            write(dependency)
        sequence.append(name)

    # After sharing, each value's factors of the data alone (2 c_7 of 2 c_7 t_1) as one constant: `refold`.
    definitions = {name: (value[0], refold(value[1])) if isinstance(value, tuple) else refold(value)
                   for name, value in definitions.items()}
    values = [refold(value) for value in reduced[len(exponentials):]]

    def calls(value):        # a library call (log, exp, a fractional power): every xmm register is lost across it
        if isinstance(value, tuple):
            return True
        return any(
            isinstance(node, (sp.log, sp.exp, LOG1P, EXPM1)) or (node.is_Pow and not node.exp.is_Integer
                                                                 and node.exp != sp.S.Half)
            for node in sp.preorder_traversal(value))

    def closure(value, seen):
        for dependency in needs(value[1] if isinstance(value, tuple) else value):
            if dependency not in seen:
                seen.add(dependency)
                closure(definitions[dependency], seen)
        return seen

    # The targets that need no call first (they free their inputs' registers), then the calls one after the other,
    # then the rest, each right after what it needs: fewer values are kept across the calls (spilled and reloaded).
    closures = [closure(value, set()) for value in values]
    early = [k for k, value in enumerate(values) if early_targets
             and not calls(value) and not any(isinstance(definitions[x], tuple) or calls(definitions[x])
                                             for x in closures[k])]
    needed = set().union(*(closures[k] for k in range(len(values)) if k not in early))
    for k in early:
        for dependency in needs(values[k]):
            write(dependency)
        sequence.append(k)
    for name in order:
        if name in needed and calls(definitions[name]):   # an exp_k or a temporary with a call
            write(name)
    for k, value in enumerate(values):
        if k not in early:
            for dependency in needs(value):
                write(dependency)
            sequence.append(k)
    renamed = {name: sp.Symbol(f"t_{k + 1}", real=True) for k, name in enumerate(
        name for name in sequence if not isinstance(name, int) and not isinstance(definitions[name], tuple))}
    temporaries[0] = max(temporaries[0], len(renamed))
    # The checks of exp(n B_k) <= max_exponent for the signs of the powers n that the expressions use (1/exp(B_k) is
    # exp(-B_k)): what a check of each exp's own argument did.
    signs = {symbol: set() for symbol, _ in exponentials}
    for expr in list(expressions) + [argument for _, argument in exponentials]:
        nodes = sp.preorder_traversal(sp.sympify(expr))
        for node in nodes:
            if node.is_Pow and node.base in signs:
                signs[node.base].add(1 if node.exp > 0 else -1)
                nodes.skip()
            elif node in signs:
                signs[node].add(1)
    lines = []
    for name in sequence:
        if isinstance(name, int):
            lines.append(wrap(f"{targets[name]} = {fortran(values[name].xreplace(renamed))}", indent))
            continue
        value = definitions[name]
        if isinstance(value, tuple):
            argument = fortran(value[1].xreplace(renamed))
            check = {(1,): f"{argument} <= max_exponent", (-1,): f"-({argument}) <= max_exponent",
                     (-1, 1): f"abs({argument}) <= max_exponent"}[tuple(sorted(signs[name]))]
            lines += [wrap(f"if (.not. ({check})) then", indent),
                      INDENT*(indent + 1) + "stat = domain_overflow", INDENT*(indent + 1) + "return",
                      INDENT*indent + "end if", wrap(f"{name.name} = exp({argument})", indent)]
        else:
            lines.append(wrap(f"{fortran(renamed[name])} = {fortran(value.xreplace(renamed))}", indent))
    return lines


def statements(lines):
    """The Fortran statements of `lines` (strings, each possibly of several lines): a statement with its & continuations,
    an if block to its end if, as lists of lines."""
    flat = [line for text in lines for line in text.split("\n")]
    groups, k = [], 0
    while k < len(flat):
        group = [flat[k]]
        while group[-1].rstrip().endswith("&"):
            k += 1
            group.append(flat[k])
        if group[0].lstrip().startswith("if (") and group[-1].rstrip().endswith(" then"):
            depth = len(group[0]) - len(group[0].lstrip())
            while not (flat[k].lstrip() == "end if" and len(flat[k]) - len(flat[k].lstrip()) == depth):
                k += 1
                group.append(flat[k])
        groups.append(group)
        k += 1
    return groups


def sunk(lines):
    """`lines` with each assignment to a plain name that calls no log or exp moved down to right before the first
    statement that uses the name (the calls and checks keep their order): what is needed only after a library call is
    computed after it, not kept (spilled and reloaded) across it. Values and their rounding are unchanged."""
    groups = statements(lines)
    moved_before = {}           # id of a moved statement: id of the statement it was moved in front of
    for group in reversed(list(groups)):
        text = " ".join(group)
        match = re.match(r"\s*([A-Za-z]\w*) = ", group[0])
        if not match or "log(" in text or "exp(" in text:
            continue
        used = re.compile(rf"\b{match.group(1)}\b")
        k = next(j for j, other in enumerate(groups) if other is group)
        later = next((j for j in range(k + 1, len(groups)) if used.search(" ".join(groups[j]))), None)
        if later is None:
            continue
        user = groups[later]
        if later == k + 1:      # in front of its user already
            moved_before[id(group)] = id(user)
            continue
        groups.pop(k)
        later -= 1
        while moved_before.get(id(groups[later - 1])) == id(user):   # in front of those moved there before,
            later -= 1                                               # which came after it: their order kept
        groups.insert(later, group)
        moved_before[id(group)] = id(user)
    return [line for group in groups for line in group]


def running_sum(lines, n, indent):
    """`lines` (with the targets f(1) ... f(n) written each once) followed, after each f(k), by f_sum = f_sum + f(k)
    as soon as f(1) ... f(k - 1) are in it: the sum f(1) + f(2) + ... + f(n) in that order, with its rounding, while
    the values are at hand, not kept for a sum at the end; then the check that it is a finite number."""
    out, done, next_index = [], set(), 1
    for group in statements(lines):
        out += group
        match = re.match(r"\s*f\((\d+)\) = ", group[0])
        if match:
            done.add(int(match.group(1)))
            while next_index in done:
                out.append(INDENT*indent + ("f_sum = f(1)" if next_index == 1 else f"f_sum = f_sum + f({next_index})"))
                next_index += 1
    assert next_index == n + 1, "every f(k) written once"
    return out + [wrap("if (.not. (abs(f_sum) <= huge(1.0_real64))) stat = domain_overflow", indent)]


def declare(names, indent):
    """real(real64) :: names (wrapped)."""
    return wrap("real(real64) :: " + ", ".join(names), indent) if names else None


def temporaries_declaration(count, indent):
    return declare([f"t_{i}" for i in range(1, count + 1)], indent)


def lines_of(*parts):
    """The text of lines and lists of lines, None left out."""
    out = []
    for part in parts:
        if part is None:
            continue
        out.extend(part if isinstance(part, list) else [part])
    return "\n".join(out)


def number(value):
    """A real64 literal of a Python float."""
    return f"{float(value)!r}_real64"


# ---------------------------------------------------------------------------------- differences

LOG1P, EXPM1 = sp.Function("log1p"), sp.Function("expm1")   # the C library's (src/util/special_functions)


def difference(expr, at_a, at_b, delta):
    """expr(b) - expr(a) without cancellation, for an expression of the symbols that at_a, at_b and delta map
    to their values at a and b and to b - a: sums term by term, products by D(f g) = D(f) g_b + f_a D(g),
    integer powers by their factored differences, square roots by D(f)/(sqrt(f_a) + sqrt(f_b)),
    log by log1p(D(f)/f_a), exp by exp(f_a) expm1(D(f)), other powers as exp(e log f) (what
    src/model/pendulum/thermo_variable.f90 did by hand). The discrete gradients divide this difference by
    |b - a|: a plain f(b) - f(a) would hand them the rounding of two values of size |f|."""
    expr = sp.sympify(expr)
    if not expr.free_symbols & set(delta):
        return sp.Integer(0)
    if expr in delta:
        return delta[expr]
    a, b = expr.subs(at_a, simultaneous=True), expr.subs(at_b, simultaneous=True)
    if expr.is_Add:
        return sp.Add(*(difference(term, at_a, at_b, delta) for term in expr.args))
    if expr.is_Mul:
        first, rest = expr.args[0], sp.Mul(*expr.args[1:])
        return (difference(first, at_a, at_b, delta)*rest.subs(at_b, simultaneous=True)
                + first.subs(at_a, simultaneous=True)*difference(rest, at_a, at_b, delta))
    if isinstance(expr, sp.log):
        return LOG1P(difference(expr.args[0], at_a, at_b, delta)/expr.args[0].subs(at_a, simultaneous=True))
    if isinstance(expr, sp.exp):
        return a*EXPM1(difference(expr.args[0], at_a, at_b, delta))
    if expr.is_Pow:
        base, exponent = expr.args
        if exponent.free_symbols & set(delta):
            return difference(sp.exp(exponent*sp.log(base), evaluate=False), at_a, at_b, delta)
        d_base = difference(base, at_a, at_b, delta)
        base_a, base_b = base.subs(at_a, simultaneous=True), base.subs(at_b, simultaneous=True)
        if exponent.is_Integer and exponent > 0:
            return d_base*sp.Add(*(base_a**k*base_b**(exponent - 1 - k) for k in range(int(exponent))))
        if exponent.is_Integer:
            return -difference(base**-exponent, at_a, at_b, delta)*a*b
        if exponent == sp.S.Half:
            return d_base/(sp.sqrt(base_a) + sp.sqrt(base_b))
        if exponent == -sp.S.Half:
            return -d_base*a*b/(sp.sqrt(base_a) + sp.sqrt(base_b))
        return a*EXPM1(exponent*LOG1P(d_base/base_a))
    raise DescriptionError(f"no cancellation-free difference of {expr} (a function the generator does not know)")


# ---------------------------------------------------------------------------------- the symbolic model

def load(path):
    """The ModelDescriptions of the description file at `path`: its `model`, or its `models` (a list: one
    description with switches, as the double pendulum's ladder of rungs)."""
    spec = importlib.util.spec_from_file_location(f"description_{Path(path).parent.name}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    if hasattr(module, "models"):
        return list(module.models)
    if not hasattr(module, "model"):
        raise DescriptionError("it defines no `model` (a ModelDescription) and no `models` (a list of them)")
    return [module.model]


def solve_one(equation, unknown, what):
    """The one solution of equation = 0 for unknown (a closed-form inverse)."""
    solutions = sp.solve(equation, unknown, dict=False)
    real = [s for s in solutions if not s.has(sp.I)]
    if len(real) != 1:
        raise DescriptionError(f"{what}: SymPy finds {len(real)} real closed forms ({solutions}); give it in "
                               f"the subsystem's `inverses`")
    return sp.simplify(real[0])


def thermodynamics(part):
    """{variable: (U, S, theta, tau_of_temperature)} of a subsystem in its invariants and tau (the
    symbol `tau`; tau_of_temperature in the symbol `theta`): from U(x, s) or psi(x, theta) by
    eq. (2) and the closed-form inverses (docs/formulation.md section 3's table)."""
    tau = sp.Symbol("tau", real=True)
    theta, energy, entropy = TEMPERATURE, ENERGY_LEVEL, ENTROPY_LEVEL
    forms = {}
    if not part.thermal:        # (U, S) = (W, 0) whatever the variable; no temperature, no tau
        if any(form is not None for form in (part.energy_of_entropy, part.free_energy_of_temperature,
                                             part.energy_and_entropy_of_temperature)):
            raise DescriptionError(f"subsystem {part.name}: a mechanical subsystem has no thermodynamic form "
                                   "(internal_energy, free_energy, energy_and_entropy): give stored_energy(W)")
        if part.stored_energy_of_invariants is None:
            raise DescriptionError(f"subsystem {part.name}: a mechanical subsystem without stored_energy(W)")
        return {variable: (logs_of_powers(part.stored_energy_of_invariants), sp.Integer(0), None, None)
                for variable in THERMO_VARIABLES}
    if part.energy_of_entropy is not None:
        s = part.entropy
        u_of_s = part.energy_of_entropy
        theta_of_s = sp.simplify(sp.diff(u_of_s, s))
        s_of_theta = part.inverses.get("temperature") or solve_one(theta_of_s - theta, s, f"{part.name}: s(theta)")
        s_of_u = part.inverses.get("internal_energy") or solve_one(u_of_s - energy, s, f"{part.name}: s(u)")
        forms["entropy"] = (u_of_s.subs(s, tau), tau, theta_of_s.subs(s, tau), s_of_theta)
        forms["temperature"] = (sp.simplify(u_of_s.subs(s, s_of_theta)).subs(theta, tau), s_of_theta.subs(theta, tau),
                                tau, theta)
        forms["internal_energy"] = (tau, s_of_u.subs(energy, tau), sp.simplify(theta_of_s.subs(s, s_of_u)).subs(
            energy, tau), sp.simplify(u_of_s.subs(s, s_of_theta)))
    elif part.free_energy_of_temperature is not None:
        t = part.temperature_symbol
        psi = part.free_energy_of_temperature
        s_of_t = sp.simplify(-sp.diff(psi, t))
        u_of_t = sp.simplify(psi + t*s_of_t)
        t_of_s = part.inverses.get("entropy") or solve_one(s_of_t - entropy, t, f"{part.name}: theta(s)")
        t_of_u = part.inverses.get("internal_energy") or solve_one(u_of_t - energy, t, f"{part.name}: theta(u)")
        forms["temperature"] = (u_of_t.subs(t, tau), s_of_t.subs(t, tau), tau, theta)
        forms["entropy"] = (sp.simplify(u_of_t.subs(t, t_of_s)).subs(entropy, tau), tau, t_of_s.subs(entropy, tau),
                            s_of_t.subs(t, theta))
        forms["internal_energy"] = (tau, sp.simplify(s_of_t.subs(t, t_of_u)).subs(energy, tau),
                                    t_of_u.subs(energy, tau), u_of_t.subs(t, theta))
    elif part.energy_and_entropy_of_temperature is not None:
        t = part.temperature_symbol
        u_of_t, s_of_t = part.energy_and_entropy_of_temperature
        if sp.simplify(sp.diff(u_of_t, t) - t*sp.diff(s_of_t, t)) != 0:
            raise DescriptionError(f"subsystem {part.name}: du/dtheta != theta ds/dtheta: (u, s) derive from no free "
                                   "energy u - theta s")
        missing = {"entropy", "internal_energy"} - set(part.inverses)
        if missing:
            raise DescriptionError(f"subsystem {part.name}: energy_and_entropy needs the inverses {sorted(missing)}")
        t_of_s, t_of_u = part.inverses["entropy"], part.inverses["internal_energy"]
        for level, inverse, value in ((entropy, t_of_s, s_of_t), (energy, t_of_u, u_of_t)):
            check_inverse(part, level, inverse, value.subs(t, inverse))
        forms["temperature"] = (u_of_t.subs(t, tau), s_of_t.subs(t, tau), tau, theta)
        forms["entropy"] = (u_of_t.subs(t, t_of_s).subs(entropy, tau), tau, t_of_s.subs(entropy, tau),
                            s_of_t.subs(t, theta))
        forms["internal_energy"] = (tau, s_of_t.subs(t, t_of_u).subs(energy, tau), t_of_u.subs(energy, tau),
                                    u_of_t.subs(t, theta))
        return {variable: forms[variable] for variable in THERMO_VARIABLES}
    else:
        raise DescriptionError(f"subsystem {part.name}: neither internal_energy(U, s), free_energy(psi, theta) nor "
                               "energy_and_entropy(u, s, theta)")
    return {variable: tuple(logs_of_powers(sp.sympify(e)) for e in forms[variable]) for variable in THERMO_VARIABLES}


def check_inverse(part, level, inverse, composed):
    """That `inverse` (theta at the level `level` of s or u) inverts: composed, s or u at theta = inverse, equals
    the level at random points of the invariants and parameters (numerically: simplify folds too slowly)."""
    random = Random(42)
    symbols = sorted(composed.free_symbols - {level}, key=lambda x: x.name)
    for _ in range(3):
        point = {x: random.uniform(0.5, 1.5) for x in symbols}
        value = random.uniform(-0.1, 0.1) if level == ENTROPY_LEVEL else random.uniform(0.9, 1.1)
        got = complex(composed.subs(point).subs(level, value).evalf(30))
        if abs(got - value) > 1e-20*(1 + abs(value)):
            raise DescriptionError(f"subsystem {part.name}: the inverse theta = {inverse} does not invert at {point}: "
                                   f"{got} != {value}")


def rounding_scale(expr):
    """A bound on the sizes of the terms `expr` is summed from, for its rounding error (invariant_function's
    values_and_temperature): sums and products of the parts' scales, a power's of its base's, |log f| + 1 for a
    log (its absolute error is eps whatever its size), |exp f| (1 + scale(f)) for an exp; |x| for a symbol or number.
    So Cap (theta - theta_ref) weighs Cap (theta + theta_ref), not the small difference it is."""
    if expr.is_Add:
        return sp.Add(*(rounding_scale(term) for term in expr.args))
    if expr.is_Mul:
        return sp.Mul(*(rounding_scale(factor) for factor in expr.args))
    if expr.is_Pow and expr.exp.is_Rational:
        return rounding_scale(expr.base)**expr.exp
    if isinstance(expr, sp.log):
        return sp.Abs(expr, evaluate=False) + 1
    if isinstance(expr, sp.exp):
        return expr*(1 + rounding_scale(expr.args[0]))
    return expr if expr.is_nonnegative else sp.Abs(expr, evaluate=False)    # unevaluated: no arg() of a power


def logs_of_powers(expr):
    """log(b**e) as e log(b) (SymPy's simplify folds them; the power would overflow first)."""
    return expr.replace(lambda x: isinstance(x, sp.log) and x.args[0].is_Pow,
                        lambda x: x.args[0].exp*sp.log(x.args[0].base))


class SymbolicModel:
    """The description's model as the interface needs it: state layout, partials, the field."""

    def __init__(self, description):
        self.d = description
        if not description.subsystems:
            raise DescriptionError("a model needs at least one subsystem")
        # A model's subsystems are all thermal or all mechanical (mechanical_subsystem: no tau column, S_a = 0).
        self.mechanical = not any(part.thermal for part in description.subsystems)
        if not self.mechanical and not all(part.thermal for part in description.subsystems):
            raise DescriptionError("subsystems with and without a thermodynamic variable: a model's subsystems are "
                                   "all thermal or all mechanical (model_interface's temperature_count)")
        self.tau_symbols = [description.tau(part) if part.thermal else None for part in description.subsystems]
        self.state = [column.symbol for column in description.columns] + [tau for tau in self.tau_symbols if tau]
        self.index = {symbol: i for i, symbol in enumerate(self.state)}
        self.parameters = [parameter.symbol for parameter in description.parameters]
        self.forms = [thermodynamics(part) for part in description.subsystems]
        self.invariant_names = [[inv.symbol.name for inv in part.invariants] + (["tau"] if part.thermal else [])
                                for part in description.subsystems]
        # The partials' symbols, partials(i, k, a) -> Symbol, and their Fortran positions.
        self.partials = {}
        for a, part in enumerate(description.subsystems):
            for i, name in enumerate(self.invariant_names[a]):
                for k, potential in enumerate(("U", "S")):
                    self.partials[part.partial(potential, name)] = (i + 1, k + 1, a + 1)
        self.check()

    def check(self):
        names = [symbol.name for symbol in self.state + self.parameters + list(self.partials)]
        clashes = sorted({name for name in names if names.count(name) > 1 or name.startswith("t_")
                          or name in ("x", "z", "f", "tau", "theta", "self", "stat", "partials")})
        if clashes:
            raise DescriptionError(f"names that clash with each other or with the generated code's: {clashes}")
        for a, part in enumerate(self.d.subsystems):
            for inv in part.invariants:
                unknown = inv.expression.free_symbols - set(self.state) - set(self.parameters)
                if unknown:
                    raise DescriptionError(f"subsystem {part.name}: invariant {inv.symbol} uses {sorted(map(str, unknown))}, "
                                           "not state columns or parameters")
                if sp.Poly(inv.expression, *self.state).total_degree() > 2:
                    raise DescriptionError(f"subsystem {part.name}: invariant {inv.symbol} = {inv.expression} is not "
                                           "at most quadratic in z (EME's exact midpoint gradient needs it)")
        if sp.Poly(self.d.mechanical_energy, *self.state).total_degree() > 2:
            raise DescriptionError("the mechanical energy is not at most quadratic in z (its cancellation-free "
                                   "difference is the midpoint gradient's)")
        for (row, column), entry in self.d.poisson_entries.items():
            if entry.free_symbols - set(self.parameters):
                raise DescriptionError(f"L0[{row}, {column}] = {entry} depends on the state: poisson_matrix_0 has no z")
        if self.mechanical and self.d.friction_entries:
            raise DescriptionError("K0 entries in a model without thermodynamic variables: dissipation needs a "
                                   "subsystem's temperature")
        # K0 may depend on the mechanical columns of z (friction_matrix_0_at), the temperatures, the partials and the
        # parameters; not on a thermodynamic column, whose meaning (s, theta or u) changes with the variable.
        temperatures = {part.temperature for part in self.d.subsystems if part.thermal}
        allowed = set(self.state) - set(self.tau_symbols) | set(self.parameters) | set(self.partials) | temperatures
        for (row, column), entry in self.d.friction_entries.items():
            on_tau = entry.free_symbols & set(self.tau_symbols)
            if on_tau:
                raise DescriptionError(f"K0[{row}, {column}] = {entry} depends on the thermodynamic column "
                                       f"{sorted(map(str, on_tau))}, which is s, theta or u by the variable: write "
                                       "it through the subsystem's temperature (or partials)")
            unknown = entry.free_symbols - allowed
            if unknown:
                raise DescriptionError(f"K0[{row}, {column}] = {entry} uses {sorted(map(str, unknown))}: not a "
                                       "mechanical column of z, a parameter, a subsystem's temperature or partial")
        self.check_friction_degeneracy()

    def check_friction_degeneracy(self):
        """K grad E = 0 (eq. (5)) asks K0 M_E^T grad E = 0, where M_E^T grad E is the mechanical energy's gradient
        on the mechanical columns and 1 on the tau columns (docs/formulation.md section 4), whatever the partials:
        checked at random points of the columns, parameters, partials and temperatures (numerically, as
        check_inverse: simplify may not fold what cancels), so that a K0 which would not conserve E is refused
        here, naming its row, rather than by the conformance kit after a build."""
        if not self.d.friction_entries:
            return
        k0 = self.matrix(self.d.friction_entries, temperatures=False)
        driving = sp.Matrix([sp.diff(self.d.mechanical_energy, z) for z in self.state])
        for tau in self.tau_symbols:
            if tau is not None:
                driving[self.index[tau]] = 1
        product = k0*driving
        temperatures = [part.temperature for part in self.d.subsystems if part.thermal]
        symbols = sorted(set().union(*(e.free_symbols for e in list(k0) + list(driving))) | set(temperatures),
                         key=lambda x: x.name)
        random = Random(42)
        for _ in range(3):
            point = {x: random.uniform(0.5, 1.5) for x in symbols}
            for i, entry in enumerate(product):
                value = float(entry.subs(point))
                size = sum(abs(float(k0[i, j].subs(point))*float(driving[j].subs(point))) for j in range(len(self.state)))
                if abs(value) > 1e-12*max(size, 1e-300):
                    raise DescriptionError(f"K0 M_E^T grad E != 0 in row {self.state[i]}: "
                                           f"{sp.sstr(sp.expand(entry))} (with M_E^T grad E = the mechanical energy's "
                                           "gradient on the mechanical columns, 1 on the tau columns), so K grad E = 0 "
                                           "fails and E is not conserved: a friction on a momentum whose energy is "
                                           "mechanical needs its (p, tau) and (tau, tau) entries too "
                                           "(docs/formulation.md section 11)")

    def friction_uses_state(self):
        """Whether a K0 entry depends on z (then the model writes friction_matrix_0_at(z, partials))."""
        return any(entry.free_symbols & set(self.state) for entry in self.d.friction_entries.values())

    def temperature_of_partials(self, a):
        """Theta_a = d_tau U_a / d_tau S_a of eq. (2), in the partials' symbols."""
        part = self.d.subsystems[a]
        return part.partial("U", "tau")/part.partial("S", "tau")

    def with_temperatures(self, expr):
        """expr with the subsystems' Theta_a written through the partials."""
        return sp.sympify(expr).subs({part.temperature: self.temperature_of_partials(a)
                                      for a, part in enumerate(self.d.subsystems) if part.thermal})

    def matrix(self, entries, temperatures=True):
        n = len(self.state)
        matrix = sp.zeros(n, n)
        for (row, column), entry in entries.items():
            if row not in self.index or column not in self.index:
                raise DescriptionError(f"matrix entry ({row}, {column}): not a column of z")
            matrix[self.index[row], self.index[column]] = self.with_temperatures(entry) if temperatures else entry
        return matrix

    def invariant_gradient(self, a, potential):
        """grad_z H_a from the partials (the chain through x_a(z); tau_a's own column last)."""
        part = self.d.subsystems[a]
        gradient = sp.zeros(len(self.state), 1)
        for inv in part.invariants:
            for j, z in enumerate(self.state):
                gradient[j] += part.partial(potential, inv.symbol.name)*sp.diff(inv.expression, z)
        if part.thermal:
            gradient[self.index[self.tau_symbols[a]]] += part.partial(potential, "tau")
        return gradient

    def mielke_transpose(self, potential):
        """M_H^T of eq. (7) in z's layout (docs/formulation.md section 4)."""
        n = len(self.state)
        mt = sp.eye(n)
        for a, part in enumerate(self.d.subsystems):
            if not part.thermal:        # no tau: M_H is the identity on its columns
                continue
            column = self.index[self.tau_symbols[a]]
            d_tau = part.partial(potential, "tau")
            omega_gradient = self.invariant_gradient(a, potential)
            for j in range(n):
                if j != column and j < len(self.d.columns):
                    mt[j, column] = -omega_gradient[j]/d_tau
            mt[column, column] = 1/d_tau
        return mt

    def field(self, simplified=True):
        """f = M_S L0 M_S^T grad E + M_E K0 M_E^T grad S (eq. (8)) in z, partials and parameters; with
        simplified=False as the product gives it, K0's temperatures Theta_a kept as their symbols."""
        grad_e = sp.Matrix([sp.diff(self.d.mechanical_energy, z) for z in self.state])
        grad_s = sp.zeros(len(self.state), 1)
        for a, part in enumerate(self.d.subsystems):
            grad_e += self.invariant_gradient(a, "U")
            if part.thermal:            # a mechanical subsystem's S_a is 0
                grad_s += self.invariant_gradient(a, "S")
        mt_s, mt_e = self.mielke_transpose("S"), self.mielke_transpose("U")
        l0, k0 = self.matrix(self.d.poisson_entries), self.matrix(self.d.friction_entries, temperatures=simplified)
        f = mt_s.T*(l0*(mt_s*grad_e)) + mt_e.T*(k0*(mt_e*grad_s))
        return [sp.simplify(entry) for entry in f] if simplified else list(f)


# ---------------------------------------------------------------------------------- code pieces

def parameter_locals(symbolic, expressions, owner="self%parameters"):
    """Declarations and assignments of the parameters that `expressions` use."""
    used = set().union(*(sp.sympify(e).free_symbols for e in expressions)) if expressions else set()
    names = [p.name for p in symbolic.parameters if p in used]
    return names, [f"{name} = {owner}%{name}" for name in names]


def guards(expressions, indent, positive=()):
    """Domain checks before evaluating: the positive invariants `positive` (symbols) > 0
    (domain_nonpositive_length), every other log's argument > 0 (domain_nonpositive_temperature)
    and every exp's argument below max_exponent (domain_overflow)."""
    logs, exps = set(), set()
    for expr in expressions:
        logs |= {atom.args[0] for atom in sp.sympify(expr).atoms(sp.log)}
        exps |= {atom.args[0] for atom in sp.sympify(expr).atoms(sp.exp)}
    lines = []
    for symbol in positive:
        lines += [INDENT*indent + f"if (.not. ({fortran(symbol)} > 0.0_real64)) then",
                  INDENT*(indent + 1) + "stat = domain_nonpositive_length", INDENT*(indent + 1) + "return",
                  INDENT*indent + "end if"]
    for argument in sorted(logs - set(positive), key=sp.default_sort_key):
        lines += [wrap(f"if (.not. ({fortran(argument)} > 0.0_real64)) then", indent),
                  INDENT*(indent + 1) + "stat = domain_nonpositive_temperature", INDENT*(indent + 1) + "return",
                  INDENT*indent + "end if"]
    for argument in sorted(exps, key=sp.default_sort_key):
        lines += [wrap(f"if (.not. ({fortran(argument)} <= max_exponent)) then", indent),
                  INDENT*(indent + 1) + "stat = domain_overflow", INDENT*(indent + 1) + "return",
                  INDENT*indent + "end if"]
    return lines, bool(logs - set(positive)), bool(exps)


def log_guards(expressions, indent, positive, fold=lambda e: e):
    """guards() without the exponentials' checks (straight_line writes them where each exp is computed) and without
    the logs whose argument is positive wherever the positive invariants `positive` are (log(C/l0^2) after C > 0);
    the arguments printed through `fold`."""
    assume = {x: sp.Dummy(positive=True) for x in positive}
    logs = {atom.args[0] for e in expressions for atom in sp.sympify(e).atoms(sp.log)}
    logs = {argument for argument in logs if not argument.xreplace(assume).is_positive}
    lines, has_log, _ = guards([sp.log(fold(argument), evaluate=False) for argument in logs], indent, positive)
    return lines, has_log


def header(description, path, what):
    return (f"!> Generated by src/model/generator/generate_model.py from {path}; do not edit (make generate).\n"
            f"!> {what}")


# ---------------------------------------------------------------------------------- the potentials

def unpack(symbols_used, names, source, indent):
    """`name = source(i)` for the names (in order) that the code uses."""
    used = {s.name for s in symbols_used}
    return [INDENT*indent + f"{name} = {source}({i + 1})" for i, name in enumerate(names) if name in used]


def subsystem_cases(cases, indent):
    """select case over the subsystem, then over the thermodynamic variable: cases is a list of
    (part, [(variable, lines)])."""
    lines = [INDENT*indent + "select case (self%subsystem)"]
    for a, (part, by_variable) in enumerate(cases):
        lines.append(INDENT*indent + f"case ({a + 1})  ! {part.label}")
        lines.append(INDENT*(indent + 1) + "select case (self%variable)")
        for variable, body in by_variable:
            lines.append(INDENT*(indent + 1) + f"case (tau_{variable})")
            lines += body
        lines.append(INDENT*(indent + 1) + "end select")
    lines.append(INDENT*indent + "end select")
    return lines


def shared_roots(positive, *groups):
    """The fractional powers b**(p/q) of the positive invariants b in the expression lists `groups` as
    integer powers of one root b**(1/q) each: ([(root symbol, its power of b)], groups rewritten). One pow
    instead of one per exponent (U = exp(2 s/3)/v**(2/3) has v**(-2/3), v**(-5/3) and v**(-8/3) in its
    derivatives)."""
    roots = {}

    def is_root_power(e):
        return e.is_Pow and e.base in positive and e.exp.is_Rational and not e.exp.is_Integer

    def as_root(e):
        key = (e.base, e.exp.q)
        if key not in roots:
            roots[key] = sp.Symbol(f"{e.base.name}_root_{e.exp.q}", real=True)
        return roots[key]**e.exp.p

    rewritten = [[sp.sympify(e).replace(is_root_power, as_root) for e in group] for group in groups]
    return [(root, base**sp.Rational(1, q)) for (base, q), root in roots.items()], rewritten


# The procedures of invariant_functions (src/structure/invariant_function.f90) every potential module writes:
# their arguments and declarations, one text for the model's, the mechanical and the element's modules.
PROCEDURE_ARGUMENTS = {
    "evaluate": ("self, x, f, grad, hess, stat", ['real(real64), intent(in) :: x(:)', 'real(real64), intent(out) :: f(:), grad(:, :)', 'real(real64), intent(out), optional :: hess(:, :, :)', 'integer, intent(out) :: stat']),
    "difference": ("self, a, b, delta, stat", ['real(real64), intent(in) :: a(:), b(:)', 'real(real64), intent(out) :: delta(:)', 'integer, intent(out) :: stat']),
    "temperature": ("self, x, theta, stat", ['real(real64), intent(in) :: x(:)', 'real(real64), intent(out) :: theta', 'integer, intent(out) :: stat']),
    "tau_from_temperature": ("self, mechanical, theta, tau, stat", ['real(real64), intent(in) :: mechanical(:)', 'real(real64), intent(in) :: theta', 'real(real64), intent(out) :: tau', 'integer, intent(out) :: stat']),
    "values_and_temperature": ("self, x, f, theta, stat, scales", ['real(real64), intent(in) :: x(:)', 'real(real64), intent(out) :: f(:), theta', 'integer, intent(out) :: stat', 'real(real64), intent(out), optional :: scales(:)']),
}


def procedure_head(routine, name):
    """The first lines of the generated procedure `routine` of {name}_potentials: its statement and declarations."""
    arguments, declarations = PROCEDURE_ARGUMENTS[routine]
    return "\n".join([f"  pure subroutine {routine}({arguments})", f"    class({name}_potentials), intent(in) :: self",
                      *(f"    {line}" for line in declarations)])


def potential_module(symbolic, source):
    d = symbolic.d
    name = d.name
    tau = sp.Symbol("tau", real=True)
    codes, temporaries = {"domain_nonpositive_temperature"}, [0]
    evaluate_cases, temperature_cases, inverse_cases, difference_cases = [], [], [], []
    locals_ = {"evaluate": set(), "temperature": set(), "inverse": set(), "difference": set(), "scale": set()}
    scale_cases, scale_temporaries = [], [0]
    difference_temporaries = [0]
    locals_order = []
    for a, part in enumerate(d.subsystems):
        invariants = [inv.symbol for inv in part.invariants] + [tau]
        names = [x.name for x in invariants]
        positive = [inv.symbol for inv in part.invariants if inv.positive]
        codes |= {"domain_nonpositive_length"} if positive else set()
        locals_order += [x for x in names if x not in locals_order]
        evaluate_body, temperature_body, inverse_body, difference_body, scale_body = [], [], [], [], []
        for variable in THERMO_VARIABLES:
            u, s, temperature, tau_of_theta = symbolic.forms[a][variable]
            values = [u, s]
            grads = [(i, k, sp.diff(f, x)) for k, f in enumerate(values) for i, x in enumerate(invariants)]
            hessians = [(i, j, k, sp.diff(f, x, y)) for k, f in enumerate(values)
                        for i, x in enumerate(invariants) for j, y in enumerate(invariants)]
            targets = [f"f({k + 1})" for k in range(2)] + [f"grad({i + 1}, {k + 1})" for i, k, g in grads if g != 0]
            exprs = values + [g for _, _, g in grads if g != 0]
            hess_targets = [f"hess({i + 1}, {j + 1}, {k + 1})" for i, j, k, h in hessians if h != 0]
            hess_exprs = [h for *_, h in hessians if h != 0]
            used = set().union(*(sp.sympify(e).free_symbols for e in exprs + hess_exprs)) | set(positive)
            locals_["evaluate"] |= {x.name for x in used if x.name in names}
            check, has_log = log_guards(values, 4, positive)
            exponentials, (exprs, hess_exprs) = shared_exponentials(positive, exprs, hess_exprs)
            codes |= {"domain_overflow"} if exponentials else set()
            roots, (exprs, hess_exprs, arguments) = shared_roots(positive, exprs, hess_exprs,
                                                                 [argument for _, argument in exponentials])
            exponentials = [(symbol, argument) for (symbol, _), argument in zip(exponentials, arguments)]
            locals_["evaluate"] |= {root.name for root, _ in roots} | {symbol.name for symbol, _ in exponentials}
            locals_order += [x for x in [root.name for root, _ in roots] + [symbol.name for symbol, _ in exponentials]
                             if x not in locals_order]
            body = unpack(used, names, "x", 4) + check
            body += [wrap(f"{root.name} = {fortran(power)}", 4) for root, power in roots]
            if hess_exprs:
                body += [INDENT*4 + "if (present(hess)) then"] + straight_line(
                    targets + hess_targets, exprs + hess_exprs, 5, temporaries, exponentials)
                body += [INDENT*4 + "else"] + straight_line(targets, exprs, 5, temporaries, exponentials)
                body += [INDENT*4 + "end if"]
            else:
                body += straight_line(targets, exprs, 4, temporaries, exponentials)
            evaluate_body.append((variable, body))

            used = sp.sympify(temperature).free_symbols | set(positive)
            locals_["temperature"] |= {x.name for x in used if x.name in names}
            check, has_log, has_exp = guards([temperature], 4, positive)
            codes |= {"domain_overflow"} if has_exp else set()
            temperature_body.append((variable, unpack(used, names, "x", 4) + check +
                                     [wrap(f"theta = {fortran(temperature)}", 4)]))
            if d.rounding_scales:
                # In every variable the temperature form's terms at the state's theta: U's e + Cap (theta - theta_ref)
                # weighs |e| + Cap (theta + theta_ref), S's sigma + Cap ln(theta/theta_ref) |sigma| + Cap (|ln| + 1).
                at_theta = {tau: sp.Symbol("theta", positive=True)}
                scales = [rounding_scale(sp.sympify(value).subs(at_theta))
                          for value in symbolic.forms[a]["temperature"][:2]]
                used = set().union(*(e.free_symbols for e in scales))
                locals_["scale"] |= {x.name for x in used if x.name in names[:-1]}
                scale_body.append((variable, unpack(used, names[:-1], "x", 4) +
                                   assignments(["scales(1)", "scales(2)"], scales, 4, scale_temporaries)))

            used = sp.sympify(tau_of_theta).free_symbols | set(positive)
            locals_["inverse"] |= {x.name for x in used if x.name in names[:-1]}
            check, has_log, has_exp = guards([tau_of_theta], 4, positive)
            codes |= {"domain_overflow"} if has_exp else set()
            inverse_body.append((variable, unpack(used, names[:-1], "mechanical", 4) + check +
                                 [wrap(f"tau = {fortran(tau_of_theta)}", 4)]))
            if d.differences:
                at_a = {x: sp.Symbol(f"{x.name}_a", real=True) for x in invariants}
                at_b = {x: sp.Symbol(f"{x.name}_b", real=True) for x in invariants}
                delta = {x: sp.Symbol(f"d_{x.name}", real=True) for x in invariants}
                differences = [difference(value, at_a, at_b, delta) for value in values]
                used = set().union(*(e.free_symbols for e in differences)) | set(positive)
                ends = [[e.subs(at, simultaneous=True) for e in values] for at in (at_a, at_b)]
                check = []
                for at, end in zip((at_a, at_b), ends):
                    lines, _, _ = guards(end, 4, [at[x] for x in positive])
                    check += lines
                    used |= set().union(*(e.free_symbols for e in end)) | {at[x] for x in positive}
                names_here = [n for x in invariants for n in (at_a[x].name, at_b[x].name, delta[x].name)]
                locals_["difference"] |= {x.name for x in used if x.name in names_here}
                locals_order += [n for n in names_here if n not in locals_order]
                body = [INDENT*4 + f"{at_a[x].name} = a({i + 1})" for i, x in enumerate(invariants)]
                body += [INDENT*4 + f"{at_b[x].name} = b({i + 1})" for i, x in enumerate(invariants)]
                body += [INDENT*4 + f"{delta[x].name} = b({i + 1}) - a({i + 1})" for i, x in enumerate(invariants)]
                body = [line for line in body if line.split()[0] in {x.name for x in used}]
                body += check + assignments(["delta(1)", "delta(2)"], differences, 4, difference_temporaries)
                difference_body.append((variable, body))
        evaluate_cases.append((part, evaluate_body))
        temperature_cases.append((part, temperature_body))
        scale_cases.append((part, scale_body))
        inverse_cases.append((part, inverse_body))
        difference_cases.append((part, difference_body))

    def local_declaration(routine, extra=()):
        return declare([x for x in locals_order if x in locals_[routine]] + list(extra), 2)

    parameter_type = [f"  !> The parameters of &model (src/model/{name}/description.py).", f"  type :: {name}_parameters"]
    parameter_type += [f"    real(real64) :: {p.name} = {number(p.default)}  !! {p.meaning} [{p.units}]"
                       for p in d.parameters]
    parameter_type.append(f"  end type {name}_parameters")
    temps = [f"t_{i}" for i in range(1, temporaries[0] + 1)]
    difference_text = "" if not d.differences else f"""
  !> f(b) - f(a) without cancellation (generate_model.py's `difference`: log1p, expm1, factored powers).
{procedure_head("difference", name)}
{lines_of(local_declaration("difference", [f"t_{i}" for i in range(1, difference_temporaries[0] + 1)]))}

    delta = 0.0_real64
    stat = failure_none
{lines_of(subsystem_cases(difference_cases, 2))}
  end subroutine difference
"""
    scale_text = "" if not d.rounding_scales else f"""
  !> (U, S) and the temperature, with the rounding scales of U and S (generate_model.py's `rounding_scale`: the
  !> sizes of the terms each is summed from), which the step check's balances are measured in.
{procedure_head("values_and_temperature", name)}
{lines_of(local_declaration("scale", [f"t_{i}" for i in range(1, scale_temporaries[0] + 1)] + ["g(size(x), size(f))"]))}

    theta = 0.0_real64
    if (present(scales)) scales = 0.0_real64
    call self%evaluate(x, f, g, stat=stat)
    if (stat /= failure_none) return
    call self%temperature(x, theta, stat)
    if (stat /= failure_none .or. .not. present(scales)) return
{lines_of(subsystem_cases(scale_cases, 2))}
  end subroutine values_and_temperature
"""
    text = f"""{header(d, source, f"(U_a, S_a) of the subsystems of {d.title} ({d.reference}):")}
!> values, gradients and Hessians in the invariants in each thermodynamic variable (entropy, temperature,
!> internal energy), the temperature of eq. (2) and tau from a temperature, in closed form.
module {name}_potential
  use, intrinsic :: iso_fortran_env, only: real64
  use invariant_function, only: invariant_functions
  use failures, only: failure_none, {", ".join(sorted(codes))}
  use thermo_variable_kinds, only: tau_entropy, tau_temperature, tau_internal_energy{
    chr(10) + "  use special_functions, only: log1p, expm1" if d.differences else ""}
  implicit none (type, external)
  private
  public :: {name}_parameters, {name}_potentials

{lines_of(parameter_type)}

  !> (U_a, S_a) of subsystem `subsystem` in thermodynamic variable `variable` (thermo_variable_kinds' tau_*).
  type, extends(invariant_functions) :: {name}_potentials
    type({name}_parameters) :: parameters
    integer :: subsystem = 1
    integer :: variable = tau_entropy
  contains
    procedure :: evaluate
    procedure :: temperature
    procedure :: tau_from_temperature{chr(10) + "    procedure :: difference" if d.differences else ""}{
    chr(10) + "    procedure :: values_and_temperature" if d.rounding_scales else ""}
  end type {name}_potentials

  ! Largest argument of exp that stays finite, with a margin.
  real(real64), parameter :: max_exponent = 0.9_real64*log(huge(1.0_real64))

contains

  !> f = (U, S), their gradients in the invariants (tau last) and optionally their Hessians.
{procedure_head("evaluate", name)}
{lines_of(local_declaration("evaluate", temps))}

    f = 0.0_real64
    grad = 0.0_real64
    if (present(hess)) hess = 0.0_real64
    stat = failure_none
{lines_of(subsystem_cases(evaluate_cases, 2))}
  end subroutine evaluate

  !> Theta = d_tau U / d_tau S of eq. (2) in closed form.
{procedure_head("temperature", name)}
{lines_of(local_declaration("temperature"))}

    theta = 0.0_real64
    stat = failure_none
{lines_of(subsystem_cases(temperature_cases, 2))}
    if (.not. (theta > 0.0_real64)) stat = domain_nonpositive_temperature
  end subroutine temperature

  !> tau at the mechanical invariants `mechanical` and the temperature theta (> 0).
{procedure_head("tau_from_temperature", name)}
{lines_of(local_declaration("inverse"))}

    tau = 0.0_real64
    stat = failure_none
    if (.not. (theta > 0.0_real64)) then
      stat = domain_nonpositive_temperature
      return
    end if
{lines_of(subsystem_cases(inverse_cases, 2))}
  end subroutine tau_from_temperature
{difference_text}{scale_text}
end module {name}_potential
"""
    return tidy(text)


def mechanical_potential_module(symbolic, source):
    """The potentials of a model whose subsystems have no thermodynamic variable (mechanical_subsystem): U_a = W_a(x)
    with gradient and Hessian in the invariants, S_a = 0, W_a(b) - W_a(a) without cancellation (differences), and
    no temperature: the engine asks none of a model without temperatures, a caller that does gets domain_overflow
    (tau_from_temperature stays invariant_functions' refusal); the run observes |U_a| as U_a's rounding scale."""
    d = symbolic.d
    name = d.name
    codes, temporaries, difference_temporaries = {"domain_overflow"}, [0], [0]
    evaluate_cases, difference_cases, locals_order, exponent = [], [], [], False
    locals_ = {"evaluate": set(), "difference": set()}
    for a, part in enumerate(d.subsystems):
        invariants = [inv.symbol for inv in part.invariants]
        names = [x.name for x in invariants]
        positive = [inv.symbol for inv in part.invariants if inv.positive]
        locals_order += [x for x in names if x not in locals_order]
        energy = symbolic.forms[a]["entropy"][0]
        grads = [(i, sp.diff(energy, x)) for i, x in enumerate(invariants)]
        hessians = [(i, j, sp.diff(energy, x, y)) for i, x in enumerate(invariants) for j, y in enumerate(invariants)]
        targets = ["f(1)"] + [f"grad({i + 1}, 1)" for i, g in grads if g != 0]
        exprs = [energy] + [g for _, g in grads if g != 0]
        hess_targets = [f"hess({i + 1}, {j + 1}, 1)" for i, j, h in hessians if h != 0]
        hess_exprs = [h for *_, h in hessians if h != 0]
        used = set().union(*(sp.sympify(e).free_symbols for e in exprs + hess_exprs)) | set(positive)
        locals_["evaluate"] |= {x.name for x in used if x.name in names}
        check, has_log, has_exp = guards([energy], 3, positive)
        codes |= ({"domain_nonpositive_length"} if positive else set()) | (
            {"domain_nonpositive_temperature"} if has_log else set())
        exponent = exponent or has_exp
        roots, (exprs, hess_exprs) = shared_roots(positive, exprs, hess_exprs)
        locals_["evaluate"] |= {root.name for root, _ in roots}
        locals_order += [root.name for root, _ in roots if root.name not in locals_order]
        body = unpack(used, names, "x", 3) + check + [wrap(f"{root.name} = {fortran(power)}", 3) for root, power in roots]
        if hess_exprs:
            body += [INDENT*3 + "if (present(hess)) then"] + assignments(targets + hess_targets, exprs + hess_exprs, 4,
                                                                          temporaries)
            body += [INDENT*3 + "else"] + assignments(targets, exprs, 4, temporaries) + [INDENT*3 + "end if"]
        else:
            body += assignments(targets, exprs, 3, temporaries)
        evaluate_cases.append((part, body))
        if d.differences:
            at_a = {x: sp.Symbol(f"{x.name}_a", real=True) for x in invariants}
            at_b = {x: sp.Symbol(f"{x.name}_b", real=True) for x in invariants}
            delta = {x: sp.Symbol(f"d_{x.name}", real=True) for x in invariants}
            change = difference(energy, at_a, at_b, delta)
            used = change.free_symbols | {at[x] for at in (at_a, at_b) for x in positive}
            check = []
            for at in (at_a, at_b):
                check += guards([energy.subs(at, simultaneous=True)], 3, [at[x] for x in positive])[0]
                used |= energy.subs(at, simultaneous=True).free_symbols
            names_here = [n for x in invariants for n in (at_a[x].name, at_b[x].name, delta[x].name)]
            locals_["difference"] |= {x.name for x in used if x.name in names_here}
            locals_order += [n for n in names_here if n not in locals_order]
            body = [INDENT*3 + f"{at_a[x].name} = a({i + 1})" for i, x in enumerate(invariants)]
            body += [INDENT*3 + f"{at_b[x].name} = b({i + 1})" for i, x in enumerate(invariants)]
            body += [INDENT*3 + f"{delta[x].name} = b({i + 1}) - a({i + 1})" for i, x in enumerate(invariants)]
            body = [line for line in body if line.split()[0] in {x.name for x in used}]
            difference_cases.append((part, body + check + assignments(["delta(1)"], [change], 3,
                                                                       difference_temporaries)))

    def cases(by_part):
        lines = [INDENT*2 + "select case (self%subsystem)"]
        for a, (part, body) in enumerate(by_part):
            lines += [INDENT*2 + f"case ({a + 1})  ! {part.label}"] + body
        return lines + [INDENT*2 + "end select"]

    def local_declaration(routine, extra=()):
        return declare([x for x in locals_order if x in locals_[routine]] + list(extra), 2)

    parameter_type = [f"  !> The parameters of &model (src/model/{name}/description.py).", f"  type :: {name}_parameters"]
    parameter_type += [f"    real(real64) :: {p.name} = {number(p.default)}  !! {p.meaning} [{p.units}]"
                       for p in d.parameters]
    parameter_type.append(f"  end type {name}_parameters")
    difference_text = "" if not d.differences else f"""
  !> (W(b) - W(a), 0) without cancellation (generate_model.py's `difference`: log1p, expm1, factored powers).
{procedure_head("difference", name)}
{lines_of(local_declaration("difference", [f"t_{i}" for i in range(1, difference_temporaries[0] + 1)]))}

    delta = 0.0_real64
    stat = failure_none
{lines_of(cases(difference_cases))}
  end subroutine difference
"""
    text = f"""{header(d, source, f"(U_a, S_a) of the subsystems of {d.title} ({d.reference}):")}
!> U_a = W_a of the mechanical invariants with gradient and Hessian, S_a = 0; no thermodynamic variable.
module {name}_potential
  use, intrinsic :: iso_fortran_env, only: real64
  use invariant_function, only: invariant_functions
  use failures, only: failure_none, {", ".join(sorted(codes))}{
    chr(10) + "  use special_functions, only: log1p, expm1" if d.differences else ""}
  implicit none (type, external)
  private
  public :: {name}_parameters, {name}_potentials

{lines_of(parameter_type)}

  !> (W_a, 0) of subsystem `subsystem`.
  type, extends(invariant_functions) :: {name}_potentials
    type({name}_parameters) :: parameters
    integer :: subsystem = 1
  contains
    procedure :: evaluate
    procedure :: temperature{chr(10) + "    procedure :: difference" if d.differences else ""}
  end type {name}_potentials
{chr(10) + "  ! Largest argument of exp that stays finite, with a margin." + chr(10) +
 "  real(real64), parameter :: max_exponent = 0.9_real64*log(huge(1.0_real64))" + chr(10) if exponent else ""}
contains

  !> f = (W, 0), their gradients in the invariants and optionally their Hessians.
{procedure_head("evaluate", name)}
{lines_of(local_declaration("evaluate", [f"t_{i}" for i in range(1, temporaries[0] + 1)]))}

    f = 0.0_real64
    grad = 0.0_real64
    if (present(hess)) hess = 0.0_real64
    stat = failure_none
{lines_of(cases(evaluate_cases))}
  end subroutine evaluate

  !> None: a subsystem without a thermodynamic variable has no temperature (domain_overflow).
{procedure_head("temperature", name)}

    theta = 0.0_real64
    stat = domain_overflow
  end subroutine temperature
{difference_text}
end module {name}_potential
"""
    return tidy(text)


def tidy(text):
    """No trailing blanks, no two empty lines in a row."""
    out = []
    for line in text.split("\n"):
        if line.strip() == "" and out and out[-1].strip() == "":
            continue
        out.append(line.rstrip())
    return "\n".join(out)


# ---------------------------------------------------------------------------------- the model

def state_unpack(symbolic, used, indent):
    """Locals of z's columns and of the partials that the code uses."""
    names = {symbol.name for symbol in used}
    lines = [INDENT*indent + f"{z.name} = z({i + 1})" for i, z in enumerate(symbolic.state) if z.name in names]
    lines += [INDENT*indent + f"{symbol.name} = partials({i}, {k}, {a})"
              for symbol, (i, k, a) in symbolic.partials.items() if symbol.name in names]
    return lines


def local_names(symbolic, used):
    names = {symbol.name for symbol in used}
    return [z.name for z in symbolic.state if z.name in names] + [s.name for s in symbolic.partials if s.name in names]


class ParameterConstants:
    """The subexpressions of the parameters alone, folded out of expressions into constants that the model's
    maker computes once (self%constants): 1/m1, (1 + beta^v) c_2, -eta_theta/theta_ref, ... cost nothing per
    evaluation then."""

    def __init__(self, parameters):
        self.parameters, self.values = set(parameters), {}

    def constant(self, expr):
        if expr not in self.values:
            self.values[expr] = sp.Symbol(f"constant_{len(self.values) + 1}", real=True)
            PRINTER.constant_names[self.values[expr].name] = len(self.values)
        return self.values[expr]

    def refold(self, expr):
        """expr, whose constants and parameters may stand in products and sums of their own (after sympy.cse), with
        those folded into constants again."""
        values = {symbol: value for value, symbol in self.values.items()}
        return self.fold(sp.sympify(expr).xreplace(values))

    def fold(self, expr):
        """expr with its largest subexpressions of parameters alone (not a bare parameter or number) as constants."""
        if expr.is_Atom or not expr.free_symbols:
            return expr
        if expr.free_symbols <= self.parameters:
            return self.constant(expr)
        if expr.is_Add or expr.is_Mul:
            fixed = [arg for arg in expr.args if arg.free_symbols <= self.parameters]
            rest = [self.fold(arg) for arg in expr.args if not arg.free_symbols <= self.parameters]
            if fixed:
                part = expr.func(*fixed)
                rest.insert(0, part if part.is_Atom or not part.free_symbols else self.constant(part))
            return expr.func(*rest)
        return expr.func(*(self.fold(arg) for arg in expr.args))


def continuous_field_procedure(symbolic, constants):
    """continuous_field (model_interface) composed in z: the field with the exact partials of each variable's
    potentials written in, its invariants as locals, its Jacobian by the chain rule through them; one
    straight-line body per thermodynamic variable, common subexpressions shared (what the relaxed schemes
    evaluate at every stage, issue 42 item 5)."""
    d = symbolic.d
    n = len(symbolic.state)
    field = symbolic.field(simplified=False)
    tau = sp.Symbol("tau", real=True)
    invariant_values, positive, replace = [], [], {}   # (local symbol, expression in z); their positivity
    for a, part in enumerate(d.subsystems):
        replace[a] = {tau: symbolic.tau_symbols[a]} if part.thermal else {}
        for inv in part.invariants:
            if inv.expression in symbolic.index:
                replace[a][inv.symbol] = inv.expression
                continue
            local = sp.Symbol(f"{inv.symbol.name}_{part.name}", real=True)
            replace[a][inv.symbol] = local
            invariant_values.append((local, inv.expression))
            if inv.positive:
                positive.append(local)
    chain = {local: expression for local, expression in invariant_values}
    cases, value_cases, root_names, exponential_names = [], [], set(), set()
    temporaries, value_temporaries = [0], [0]
    for variable in THERMO_VARIABLES[:1] if symbolic.mechanical else THERMO_VARIABLES:   # mechanical: one form
        exact = {}
        for a, part in enumerate(d.subsystems):
            u, s_, temperature, _ = symbolic.forms[a][variable]
            if part.thermal:
                exact[part.temperature] = temperature.subs(replace[a], simultaneous=True)   # Theta_a in closed form
            for name in symbolic.invariant_names[a]:
                symbol = tau if name == "tau" else next(inv.symbol for inv in part.invariants if inv.symbol.name == name)
                for potential, value in (("U", u), ("S", s_)):
                    exact[part.partial(potential, name)] = sp.diff(value, symbol).subs(replace[a], simultaneous=True)
        f = [sp.sympify(entry).subs(exact, simultaneous=True) for entry in field]
        jacobian = []
        for i in range(n):
            for j, z in enumerate(symbolic.state):
                entry = sp.diff(f[i], z) + sum((sp.diff(f[i], local)*sp.diff(expression, z)
                                                for local, expression in chain.items()), sp.Integer(0))
                if entry != 0:
                    jacobian.append((i, j, entry))
        check, _ = log_guards(f, 3, positive, constants.fold)
        exponentials, (f, jacobian_values) = shared_exponentials(positive, f, [e for *_, e in jacobian])
        exponential_names |= {symbol.name for symbol, _ in exponentials}
        f = [constants.fold(e) for e in f]
        jacobian = [(i, j, constants.fold(e)) for (i, j, _), e in zip(jacobian, jacobian_values)]
        exponentials = [(symbol, constants.fold(argument)) for symbol, argument in exponentials]
        roots, (f, jacobian_values, arguments) = shared_roots(positive, f, [e for *_, e in jacobian],
                                                              [argument for _, argument in exponentials])
        jacobian = [(i, j, e) for (i, j, _), e in zip(jacobian, jacobian_values)]
        exponentials = [(symbol, argument) for (symbol, _), argument in zip(exponentials, arguments)]
        root_names |= {root.name for root, _ in roots}
        head = check + [wrap(f"{root.name} = {fortran(power)}", 3) for root, power in roots]
        cases.append((variable, head + straight_line(
            [f"f({i + 1})" for i in range(n)] + [f"jacobian({i + 1}, {j + 1})" for i, j, _ in jacobian],
            f + [e for *_, e in jacobian], 3, temporaries, exponentials, constants.refold)))
        value_cases.append((variable, head + straight_line([f"f({i + 1})" for i in range(n)], f, 3, value_temporaries,
                                                           exponentials, constants.refold, early_targets=False)))
    state_names = [z.name for z in symbolic.state]
    unpack_lines = [INDENT*2 + f"{z.name} = z({i + 1})" for i, z in enumerate(symbolic.state)]
    unpack_lines += [wrap(f"{local.name} = {fortran(expression)}", 2) for local, expression in invariant_values]
    # field_values: each case reads the state itself, each entry where first needed (sunk), and sums f as it goes.
    case_unpack = [INDENT + line for line in unpack_lines]
    value_cases = [(variable, running_sum(sunk(case_unpack + body), n, 3)) for variable, body in value_cases]

    def selected(by_variable):
        if symbolic.mechanical:     # no thermodynamic variable to select by: the one body, a level less indented
            return [line[len(INDENT):] for line in "\n".join(by_variable[0][1]).split("\n")]
        lines = [INDENT*2 + "select case (self%thermo_variable)"]
        for variable, body in by_variable:
            lines += [INDENT*2 + f"case (tau_{variable})"] + body
        return lines + [INDENT*2 + "end select"]

    def declarations(count):
        return declare(state_names + [local.name for local, _ in invariant_values] + sorted(root_names)
                       + sorted(exponential_names, key=lambda name: int(name.split("_")[1]))
                       + [f"t_{i}" for i in range(1, count + 1)], 2)

    value_declarations = declare(state_names + [local.name for local, _ in invariant_values] + sorted(root_names)
                                 + sorted(exponential_names, key=lambda name: int(name.split("_")[1]))
                                 + [f"t_{i}" for i in range(1, value_temporaries[0] + 1)] + ["f_sum"], 2)
    finite = wrap("if (.not. (abs(" + " + ".join(f"f({i + 1})" for i in range(n)) + ") <= huge(1.0_real64))) "
                  "stat = domain_overflow", 2)
    return f"""
  !> f(z) with the exact partials written in (model_interface's continuous_field, composed), optionally df/dz;
  !> stat a domain code outside the potentials' domain.
  pure subroutine continuous_field(self, z, f, stat, jacobian)
    class({d.name}), intent(in) :: self
    real(real64), intent(in) :: z(:)
    real(real64), intent(out) :: f(:)
    integer, intent(out) :: stat
    real(real64), intent(out), optional :: jacobian(:, :)

    real(real64) :: z_copy({n}), f_copy({n})

    if (present(jacobian)) then
      call field_and_jacobian(self, z, f, stat, jacobian)
    else if (is_contiguous(z) .and. is_contiguous(f)) then
      call field_values(self, z, f, stat)
    else    ! a strided z or f through copies: field_values, called twice, stays a procedure of its own
      z_copy = z
      call field_values(self, z_copy, f_copy, stat)
      f = f_copy
    end if
  end subroutine continuous_field

  !> continuous_field with df/dz (not inlined, as field_values).
  pure subroutine field_and_jacobian(self, z, f, stat, jacobian)
    class({d.name}), intent(in) :: self
    real(real64), intent(in) :: z(:)
    real(real64), intent(out) :: f(:)
    integer, intent(out) :: stat
    real(real64), intent(out) :: jacobian(:, :)
{declarations(temporaries[0])}

    stat = failure_none
    jacobian = 0.0_real64
{lines_of(unpack_lines)}
{lines_of(selected(cases))}
    ! One sum, written out, for every entry's finiteness: an infinity or a NaN anywhere makes it no finite number.
{finite}
  end subroutine field_and_jacobian

  !> continuous_field without df/dz, on z and f of the state's size: contiguous (the relaxed schemes' stages are),
  !> so no stride is computed for each of their entries; not inlined (called from two places), so that
  !> continuous_field stays a dispatch and prepares nothing of the Jacobian's for it. f's finiteness check sums
  !> f(1) + ... + f(n) in that order as the entries are written (f_sum).
  pure subroutine field_values(self, z, f, stat)
    class({d.name}), intent(in) :: self
    real(real64), intent(in) :: z({n})
    real(real64), intent(out) :: f({n})
    integer, intent(out) :: stat
{value_declarations}

    stat = failure_none
{lines_of(selected(value_cases))}
  end subroutine field_values"""


def angular_momentum_procedures(symbolic):
    """momenta, conserved_in_momenta, conserved_momenta_gradient and momentum_scale of J = sum_a q_a x p_a."""
    d = symbolic.d
    name = d.name
    column = {symbol: symbolic.index[symbol] + 1 for symbol in symbolic.state}
    planar = len(d.gravity) == 2
    components = []
    for i in (2,) if planar else range(3):      # in the plane, J's component about the normal alone
        j, k = (i + 1) % 3, (i + 2) % 3
        terms = [f"z({column[q[j]]})*z({column[p[k]]}) - z({column[q[k]]})*z({column[p[j]]})"
                 for q, p in d.angular_momentum_pairs]
        components.append(wrap(f"values({len(components) + 1}) = " + " + ".join(terms), 2))
    if planar:          # none with gravity in the plane (the maker's momentum_names)
        components.insert(0, "    if (size(values) == 0) return")
    gradient = []
    for a, (q, p) in enumerate(d.angular_momentum_pairs):
        gradient.append(f"      q = [{', '.join(f'z({column[x]})' for x in q)}{', 0.0_real64' if planar else ''}]")
        targets = f"gradients([{', '.join(str(column[x]) for x in p)}], k)"
        if planar:      # a x q's components in the plane
            gradient += [f"      associate (in_space => cross(self%conserved(k)%axis, q))",
                         f"        {targets} = in_space(1:2)", "      end associate"]
        else:
            gradient.append(f"      {targets} = cross(self%conserved(k)%axis, q)")
    scale = " + ".join(f"sqrt(sum(z([{', '.join(str(column[x]) for x in q)}])**2)*sum(z([{', '.join(str(column[x]) for x in p)}])**2))"
                       for q, p in d.angular_momentum_pairs)
    return f"""
  !> The momenta J = sum_a q_a x p_a (docs/formulation.md section 2).
  pure function momenta(self, z) result(values)
    class({name}), intent(in) :: self
    real(real64), intent(in) :: z(:)
    real(real64) :: values(self%momentum_count())

{lines_of(components)}
  end function momenta

  !> The conserved components J.a of J (their axes a: `conserved`) from the momenta.
  pure function conserved_in_momenta(self, momenta) result(values)
    class({name}), intent(in) :: self
    real(real64), intent(in) :: momenta(:)
    real(real64) :: values(self%conserved_count())

    values = component_values(self%conserved, momenta)
  end function conserved_in_momenta

  !> d(J.a)/dp_b = a x q_b for each conserved axis a.
  pure function conserved_momenta_gradient(self, z) result(gradients)
    class({name}), intent(in) :: self
    real(real64), intent(in) :: z(:)
    real(real64) :: gradients(size(z), self%conserved_count())
    real(real64) :: q(3)
    integer :: k

    gradients = 0.0_real64
    do k = 1, size(gradients, 2)
{lines_of(gradient)}
    end do
  end function conserved_momenta_gradient

  !> The rounding scale of J: sum_a |q_a||p_a|.
  pure real(real64) function momentum_scale(self, z)
    class({name}), intent(in) :: self
    real(real64), intent(in) :: z(:)

{wrap("momentum_scale = " + scale, 2)}
  end function momentum_scale

  !> The cross product a x b.
  pure function cross(a, b) result(c)
    real(real64), intent(in) :: a(3), b(3)
    real(real64) :: c(3)

    c = [a(2)*b(3) - a(3)*b(2), a(3)*b(1) - a(1)*b(3), a(1)*b(2) - a(2)*b(1)]
  end function cross"""


def model_module(symbolic, source):
    d = symbolic.d
    name = d.name
    n = len(symbolic.state)
    f = symbolic.field()
    partial_symbols = list(symbolic.partials)
    df_dz = [(i, j, sp.diff(f[i], z)) for i in range(n) for j, z in enumerate(symbolic.state)]
    df_dz = [(i, j, e) for i, j, e in df_dz if e != 0]
    df_dp = [(i, symbolic.partials[symbol], sp.diff(f[i], symbol)) for i in range(n) for symbol in partial_symbols]
    df_dp = [(i, position, e) for i, position, e in df_dp if e != 0]
    temporaries = [0]
    f_targets = [f"f({i + 1})" for i in range(n)]
    derivative_targets = [f"df_dz({i + 1}, {j + 1})" for i, j, _ in df_dz]
    partial_targets = [f"df_dpartials({i + 1}, {p[0]}, {p[1]}, {p[2]})" for i, p, _ in df_dp]
    used = set().union(*(sp.sympify(e).free_symbols for e in f + [e for *_, e in df_dz] + [e for *_, e in df_dp]))
    field_lines = state_unpack(symbolic, used, 2)
    field_lines += [INDENT*2 + "if (present(df_dz) .or. present(df_dpartials)) then"]
    field_lines += assignments(f_targets + ["derivative_z(%d)" % (k + 1) for k in range(len(df_dz))]
                               + ["derivative_partials(%d)" % (k + 1) for k in range(len(df_dp))],
                               f + [e for *_, e in df_dz] + [e for *_, e in df_dp], 3, temporaries)
    field_lines += [INDENT*3 + "if (present(df_dz)) then", INDENT*4 + "df_dz = 0.0_real64"]
    field_lines += [INDENT*4 + f"{target} = derivative_z({k + 1})" for k, target in enumerate(derivative_targets)]
    field_lines += [INDENT*3 + "end if", INDENT*3 + "if (present(df_dpartials)) then",
                    INDENT*4 + "df_dpartials = 0.0_real64"]
    field_lines += [INDENT*4 + f"{target} = derivative_partials({k + 1})" for k, target in enumerate(partial_targets)]
    field_lines += [INDENT*3 + "end if", INDENT*2 + "else"]
    field_lines += assignments(f_targets, f, 3, temporaries) + [INDENT*2 + "end if"]
    field_declarations = declare(local_names(symbolic, used) + [f"t_{i}" for i in range(1, temporaries[0] + 1)]
                                 + [f"derivative_z({max(len(df_dz), 1)})",
                                    f"derivative_partials({max(len(df_dp), 1)})"], 2)

    # invariants
    invariant_lines = [INDENT*2 + "select case (a)"]
    columns_of = []
    for a, part in enumerate(d.subsystems):
        tau_column = symbolic.index[symbolic.tau_symbols[a]] + 1 if part.thermal else 0
        mechanical_columns = sorted({symbolic.index[z] + 1 for inv in part.invariants
                                     for z in inv.expression.free_symbols if z in symbolic.index})
        columns = mechanical_columns + ([tau_column] if part.thermal else [])
        columns_of.append(columns)
        values = [inv.expression for inv in part.invariants]
        invariant_lines.append(INDENT*2 + f"case ({a + 1})  ! {part.label}")
        used_here = set().union(*(e.free_symbols for e in values)) if values else set()
        invariant_lines += [wrap(f"x({i + 1}) = {fortran(e.subs({z: sp.Symbol(f'z({symbolic.index[z] + 1})') for z in used_here if z in symbolic.index}))}", 3)
                            for i, e in enumerate(values)]
        if part.thermal:
            invariant_lines.append(INDENT*3 + f"x({len(values) + 1}) = z({tau_column})")
        invariant_lines += [INDENT*3 + "if (present(dx_dz)) then", INDENT*4 + "dx_dz = 0.0_real64"]
        for i, e in enumerate(values):
            for j, column in enumerate(mechanical_columns):
                derivative = sp.diff(e, symbolic.state[column - 1])
                if derivative != 0:
                    derivative = derivative.subs({z: sp.Symbol(f"z({symbolic.index[z] + 1})")
                                                  for z in derivative.free_symbols if z in symbolic.index})
                    invariant_lines.append(wrap(f"dx_dz({i + 1}, {j + 1}) = {fortran(derivative)}", 4))
        if part.thermal:
            invariant_lines.append(INDENT*4 + f"dx_dz({len(values) + 1}, {len(columns)}) = 1.0_real64")
        invariant_lines.append(INDENT*3 + "end if")
    invariant_lines.append(INDENT*2 + "end select")

    # energies
    state_as_z = {z: sp.Symbol(f"z({i + 1})") for i, z in enumerate(symbolic.state)}
    energy = sp.expand(d.mechanical_energy)
    gradient = [sp.diff(d.mechanical_energy, z) for z in symbolic.state]
    gradient_lines = [wrap(f"gradient({j + 1}) = {fortran(g.subs(state_as_z))}", 2)
                      for j, g in enumerate(gradient) if g != 0]
    terms = sp.Add.make_args(energy)
    scale = sum((sp.Abs(term) for term in terms), sp.Integer(0))

    # L0 and K0
    l0_lines = [INDENT*2 + f"l0({symbolic.index[r] + 1}, {symbolic.index[c] + 1}) = {fortran(e)}"
                for (r, c), e in sorted(d.poisson_entries.items(), key=lambda item: (symbolic.index[item[0][0]],
                                                                                     symbolic.index[item[0][1]]))]
    k0_entries = {(symbolic.index[r] + 1, symbolic.index[c] + 1): symbolic.with_temperatures(e)
                  for (r, c), e in d.friction_entries.items()}
    k0_used = set().union(*(e.free_symbols for e in k0_entries.values())) if k0_entries else set()
    k0_temporaries = [0]
    k0_lines = state_unpack(symbolic, k0_used, 2)
    k0_lines += assignments([f"k0({r}, {c})" for r, c in sorted(k0_entries)],
                            [k0_entries[key] for key in sorted(k0_entries)], 2, k0_temporaries)
    k0_declaration = declare(local_names(symbolic, k0_used) + [f"t_{i}" for i in range(1, k0_temporaries[0] + 1)], 2)
    if symbolic.friction_uses_state():     # K0(z, partials): its dK0/dz is in the field's df/dz
        friction_procedure, friction_arguments = "friction_matrix_0_at", "z(:), partials(:, :, :)"
        friction_head = ("  !> K0 of eq. (8) at the state z and the temperatures and partials `partials` gives.\n"
                         "  pure function friction_matrix_0_at(self, z, partials) result(k0)")
    else:
        friction_procedure, friction_arguments = "friction_matrix_0", "partials(:, :, :)"
        friction_head = ("  !> K0 of eq. (8) at the temperatures and partials `partials` gives.\n"
                         "  pure function friction_matrix_0(self, partials) result(k0)")

    # the maker
    momenta = [c for c in d.columns if c.kind == "momentum" and c.dataset]
    maker = [f"    model%parameters = parameters", "    model%thermo_variable = variable",
             f"    model%state_size = {n}",
             f"    model%max_invariants = {max(len(part.invariants) + part.thermal for part in d.subsystems)}",
             f"    allocate (model%column_names({n}))"]
    for i, column in enumerate(d.columns):
        maker.append(f"    model%column_names({i + 1}) = '{column.name}'")
    for a, part in enumerate(part for part in d.subsystems if part.thermal):
        maker.append(f"    model%column_names({len(d.columns) + a + 1}) = trim(tau_prefixes(variable))//'_{part.name}'")
    words = {"temperature": "temperatures theta_a = dU_a/dS_a of the subsystems: "
                            + ", ".join(part.label for part in d.subsystems),
             "metric_scales": f"each invariant by its scale in src/model/{name}/description.py", **d.words}
    maker += [f"    model%words%temperature = '{words['temperature']}'"]
    maker += [f"    model%words%{key} = '{words[key]}'" for key in ("energy", "entropy") if key in words]
    maker += [f"    model%words%energy_units = '{d.energy_units}'",
              f"    model%words%entropy_units = '{d.entropy_units}'",
              f"    model%words%temperature_units = '{d.temperature_units}'",
              f"    model%words%metric_scales = '{words['metric_scales']}'"]
    if d.angular_momentum_pairs and len(d.gravity) == 2:
        # In the plane: J about the normal, kept without gravity; with gravity in the plane, no momentum is kept.
        # (docs/formulation.md section 9: with gravity in the plane the model reports no momenta.)
        PRINTER.owner = "parameters"
        maker += [wrap("if (.not. any(abs([" + ", ".join(map(fortran, d.gravity)) + "]) > 0.0_real64)) then", 2),
                  wrap("model%words%momenta = 'J = " + " + ".join(f"q{a + 1}_x p{a + 1}_y - q{a + 1}_y p{a + 1}_x" for a in
                                                           range(len(d.angular_momentum_pairs))) + "'", 3),
                  "      model%words%momentum_units = 'J s'",
                  "      model%momentum_names = [character(len=8) :: 'J']",
                  "      model%conserved = [conserved_component('J', [0.0_real64, 0.0_real64, 1.0_real64])]",
                  "    else", "      allocate (model%conserved(0))", "    end if"]
        PRINTER.owner = "self%parameters"
    elif d.angular_momentum_pairs:
        PRINTER.owner = "parameters"
        maker += ["    model%words%momenta = 'J = " + " + ".join(f"q{a + 1} x p{a + 1}" for a in
                                                            range(len(d.angular_momentum_pairs))) + "'",
                  "    model%words%momentum_units = 'J s'",
                  "    model%momentum_names = [character(len=8) :: 'J_x', 'J_y', 'J_z']",
                  wrap("model%conserved = angular_momentum_components([" + ", ".join(map(fortran, d.gravity)) + "])", 2)]
        PRINTER.owner = "self%parameters"
    elif not momenta:
        maker.append("    allocate (model%momentum_names(0))")
    if momenta:
        maker.append(f"    model%momentum_names = [character(len=8) :: "
                     + ", ".join(f"'{c.name}'" for c in momenta) + "]")
        maker.append(f"    model%words%momenta = 'the momenta " + ", ".join(c.name for c in momenta) + "'")
        maker.append(f"    model%words%momentum_units = '{momenta[0].units}'")
    if d.conserved:
        maker.append("    model%conserved = [" + ", ".join(f"conserved_component('{z.name}')" for z in d.conserved)
                     + "]")
    maker.append(f"    allocate (model%subsystems({len(d.subsystems)}))")
    PRINTER.owner = "parameters"
    for a, part in enumerate(d.subsystems):
        scales = [inv.scale for inv in part.invariants]
        maker += [f"    associate (part => model%subsystems({a + 1}))",
                  f"      part%name = '{part.label}'",
                  wrap(f"allocate (part%potentials, source={name}_potentials(parameters=parameters, subsystem={a + 1}"
                       + (", variable=variable))" if part.thermal else "))"), 3),
                  f"      part%invariant_count = {len(part.invariants) + part.thermal}",
                  f"      part%columns = [{', '.join(map(str, columns_of[a]))}]",
                  f"      part%tau_column = {columns_of[a][-1] if part.thermal else 0}"]
        if not part.thermal:        # no tau: the invariants' scales alone, whatever the variable
            maker += [wrap("part%metric_scale = [" + ", ".join(fortran(e) for e in scales) + "]", 3),
                      "    end associate"]
            continue
        maker.append("      select case (variable)")
        for variable in THERMO_VARIABLES:
            maker.append(f"      case (tau_{variable})")
            maker.append(wrap("part%metric_scale = [" + ", ".join(fortran(e) for e in scales + [part.tau_scales[variable]])
                              + "]", 4))
        maker += ["      end select", "    end associate"]
    PRINTER.owner = "self%parameters"

    units_lines = [f"    units({i + 1}) = '{c.units}'" for i, c in enumerate(d.columns)]
    for a, part in enumerate(part for part in d.subsystems if part.thermal):
        units_lines.append(f"    units({len(d.columns) + a + 1}) = tau_units(self%thermo_variable)")
    momentum_procedures = []
    momentum_bindings = []
    if momenta:
        momentum_bindings.append("    procedure :: momenta")
        indices = ", ".join(str(symbolic.index[c.symbol] + 1) for c in momenta)
        momentum_procedures.append(f"""
  !> The momenta {", ".join(c.name for c in momenta)} (momentum_names).
  pure function momenta(self, z) result(values)
    class({name}), intent(in) :: self
    real(real64), intent(in) :: z(:)
    real(real64) :: values(self%momentum_count())

    values = z([{indices}])
  end function momenta""")
    if d.conserved:
        momentum_bindings += ["    procedure :: conserved_in_momenta", "    procedure :: conserved_momenta_gradient"]
        positions = [momenta.index(next(c for c in momenta if c.symbol == z)) + 1 for z in d.conserved]
        columns = [symbolic.index[z] + 1 for z in d.conserved]
        momentum_procedures.append(f"""
  !> The conserved momenta ({", ".join(z.name for z in d.conserved)}) among the momenta.
  pure function conserved_in_momenta(self, momenta) result(values)
    class({name}), intent(in) :: self
    real(real64), intent(in) :: momenta(:)
    real(real64) :: values(self%conserved_count())

    values = momenta([{", ".join(map(str, positions))}])
  end function conserved_in_momenta

  !> Their gradients in z: a unit vector each.
  pure function conserved_momenta_gradient(self, z) result(gradients)
    class({name}), intent(in) :: self
    real(real64), intent(in) :: z(:)
    real(real64) :: gradients(size(z), self%conserved_count())

    gradients = 0.0_real64
{chr(10).join(f"    gradients({column}, {k + 1}) = 1.0_real64" for k, column in enumerate(columns))}
  end function conserved_momenta_gradient""")
    constants = ParameterConstants(symbolic.parameters)
    if d.continuous_field:
        momentum_bindings.append("    procedure :: continuous_field")
        momentum_procedures.append(continuous_field_procedure(symbolic, constants))
        PRINTER.owner = "parameters"
        maker += [wrap(f"model%constants({k + 1}) = {fortran(value)}", 2)
                  for k, value in enumerate(constants.values)]
        PRINTER.owner = "self%parameters"
    if d.angular_momentum_pairs:
        momentum_bindings += ["    procedure :: momenta", "    procedure :: conserved_in_momenta",
                              "    procedure :: conserved_momenta_gradient", "    procedure :: momentum_scale"]
        momentum_procedures.append(angular_momentum_procedures(symbolic))
    tau_units = {"entropy": d.entropy_units, "temperature": d.temperature_units, "internal_energy": d.energy_units}
    field_comment = "\n".join("!>   " + line.strip() for line in d.field_text.strip().splitlines())
    tau_tables = "" if symbolic.mechanical else f"""
  !> The thermodynamic columns' names and units by variable (thermo_variable_kinds' order).
  character(len=5), parameter :: tau_prefixes(3) = [character(len=5) :: '{TAU_PREFIX["entropy"]}', '{TAU_PREFIX["temperature"]}', '{TAU_PREFIX["internal_energy"]}']
  character(len=16), parameter :: tau_units(3) = [character(len=16) :: '{tau_units["entropy"]}', '{tau_units["temperature"]}', '{tau_units["internal_energy"]}']
"""
    text = f"""{header(d, source, f"The model of {d.title} ({d.reference}):")}
!> a generic_model whose subsystems' (U_a, S_a) are {name}_potential's, with the invariants, the
!> written-out field f = M_S L0 M_S^T grad E + M_E K0 M_E^T grad S (eq. (8)) and its derivatives in z and in the
!> partials, the mechanical energy {sp.sstr(d.mechanical_energy)}, L0 and K0 as the description states them:
{field_comment}
module {name}_model
  use, intrinsic :: iso_fortran_env, only: real64
  use model_interface, only: generic_model{", conserved_component" if d.conserved or (
    d.angular_momentum_pairs and len(d.gravity) == 2) else ""}{
    ", angular_momentum_components, component_values" if d.angular_momentum_pairs else ""}
{"" if symbolic.mechanical else "  use thermo_variable_kinds, only: tau_entropy, tau_temperature, tau_internal_energy" + chr(10)}{
    "  use failures, only: failure_none, domain_nonpositive_length, domain_nonpositive_temperature, domain_overflow"
    + chr(10) if d.continuous_field else ""}{wrap(f"use {name}_potential, only: {name}_parameters, {name}_potentials", 1)}
  implicit none (type, external)
  private
  public :: {name}, make_{name}
{tau_tables}
{"  ! Largest argument of exp that stays finite, with a margin." + chr(10) +
 "  real(real64), parameter :: max_exponent = 0.9_real64*log(huge(1.0_real64))" + chr(10)
 if "max_exponent)" in "".join(momentum_procedures) else ""}
  !> The model with its parameters.
  type, extends(generic_model) :: {name}
    type({name}_parameters) :: parameters{
    chr(10) + f"    real(real64) :: constants({len(constants.values)}) = 0.0_real64  !! of the parameters alone, for the field"
    if constants.values else ""}
  contains
    procedure :: invariants
    procedure :: vector_field
    procedure :: mechanical_energy
    procedure :: mechanical_energy_gradient
    procedure :: mechanical_energy_difference
    procedure :: mechanical_energy_scale
    procedure :: poisson_matrix_0
    procedure :: {friction_procedure}
    procedure :: in_variable
    procedure :: column_units
{lines_of(momentum_bindings)}
  end type {name}

contains

  !> The model with `parameters` in thermodynamic variable `variable` (thermo_variable_kinds' tau_*).
  pure function make_{name}(parameters, variable) result(model)
    type({name}_parameters), intent(in) :: parameters
    integer, intent(in) :: variable
    type({name}) :: model

{lines_of(maker)}
  end function make_{name}

  !> x_a(z) (tau_a last), and optionally dx_dz(i, j) = d x_a(i)/d z(columns(j)).
  pure subroutine invariants(self, z, a, x, dx_dz)
    class({name}), intent(in) :: self
    real(real64), intent(in) :: z(:)
    integer, intent(in) :: a
    real(real64), intent(out) :: x(:)
    real(real64), intent(out), optional :: dx_dz(:, :)

{lines_of(invariant_lines)}
  end subroutine invariants

  !> f(z, partials) of eq. (8) written out, and optionally df/dz at fixed partials and df/dpartials.
  pure subroutine vector_field(self, z, partials, f, df_dz, df_dpartials)
    class({name}), intent(in) :: self
    real(real64), intent(in) :: z(:), partials(:, :, :)
    real(real64), intent(out) :: f(:)
    real(real64), intent(out), optional :: df_dz(:, :), df_dpartials(:, :, :, :)
{field_declarations}

{lines_of(field_lines)}
  end subroutine vector_field

  !> The mechanical energy {sp.sstr(d.mechanical_energy)}.
  pure function mechanical_energy(self, z) result(value)
    class({name}), intent(in) :: self
    real(real64), intent(in) :: z(:)
    real(real64) :: value

{wrap(f"value = {fortran(d.mechanical_energy.subs(state_as_z))}", 2)}
  end function mechanical_energy

  !> Its gradient in z.
  pure function mechanical_energy_gradient(self, z) result(gradient)
    class({name}), intent(in) :: self
    real(real64), intent(in) :: z(:)
    real(real64) :: gradient(size(z))

    gradient = 0.0_real64
{lines_of(gradient_lines)}
  end function mechanical_energy_gradient

  !> Its difference without cancellation: grad E(z_mid).(z_b - z_a), exact for an energy at most quadratic in z.
  pure function mechanical_energy_difference(self, z_a, z_b) result(delta)
    class({name}), intent(in) :: self
    real(real64), intent(in) :: z_a(:), z_b(:)
    real(real64) :: delta

    delta = dot_product(self%mechanical_energy_gradient(0.5_real64*(z_a + z_b)), z_b - z_a)
  end function mechanical_energy_difference

  !> Its rounding scale: the sum of its terms' absolute values.
  pure real(real64) function mechanical_energy_scale(self, z)
    class({name}), intent(in) :: self
    real(real64), intent(in) :: z(:)

{wrap(f"mechanical_energy_scale = {fortran(scale.subs(state_as_z))}", 2)}
  end function mechanical_energy_scale

  !> L0 of eq. (8).
  pure function poisson_matrix_0(self) result(l0)
    class({name}), intent(in) :: self
    real(real64) :: l0(self%state_size, self%state_size)

    l0 = 0.0_real64
{lines_of(l0_lines)}
  end function poisson_matrix_0

{friction_head}
    class({name}), intent(in) :: self
    real(real64), intent(in) :: {friction_arguments}
    real(real64) :: k0(self%state_size, self%state_size)
{k0_declaration or ""}

    k0 = 0.0_real64
{lines_of(k0_lines)}
  end function {friction_procedure}

  !> The same model in another thermodynamic variable.
  subroutine in_variable(self, variable, other)
    class({name}), intent(in) :: self
    integer, intent(in) :: variable
    class(generic_model), allocatable, intent(out) :: other

    allocate (other, source=make_{name}(self%parameters, variable))
  end subroutine in_variable

  !> The columns' units; the thermodynamic columns' by the variable.
  pure subroutine column_units(self, units)
    class({name}), intent(in) :: self
    character(len=*), intent(out) :: units(:)

{lines_of(units_lines)}
  end subroutine column_units
{lines_of(momentum_procedures)}

end module {name}_model
"""
    return tidy(text)


# ---------------------------------------------------------------------------------- the scene

def bounds_text(minimum, exclusive, maximum, open_maximum=False):
    """'> 0', '>= 0', 'in (0, 2]', 'in (0, 2)', 'any' of a field's bounds (open_maximum: the maximum
    itself is refused by the domain checks, not by the field)."""
    if minimum is None and maximum is None:
        return "any"
    if maximum is None:
        return f"{'>' if exclusive else '>='} {minimum:g}"
    close = ")" if open_maximum else "]"
    if minimum is None:
        return f"{'<' if open_maximum else '<='} {maximum:g}"
    return f"in {'(' if exclusive else '['}{minimum:g}, {maximum:g}{close}"


def allowed_text(bounds, units, meaning):
    words = "a real number" + ("" if bounds == "any" else " " + bounds)
    return f"{words} [{units}]: {meaning}" if meaning else f"{words} [{units}]"


def fortran_text(text, piece=60):
    """A Fortran character expression of text (quotes doubled), in literals of about `piece`
    characters joined by // (so that lines can be wrapped between them)."""
    words, pieces = text.split(" "), [""]
    for word in words:
        if pieces[-1] and len(pieces[-1]) + len(word) > piece:
            pieces.append("")
        pieces[-1] += word + " "
    pieces[-1] = pieces[-1][:-1]
    return " // ".join("'" + p.replace("'", "''") + "'" for p in pieces)


def real_field_call(name, target, bounds_args, allowed, units, temperature, count=0):
    """real_field (count 0) or reals_field (count values) of a component, bounds_args as bounds_text's."""
    minimum, exclusive, maximum = bounds_args[:3]
    options = ""
    if minimum is not None:
        options += f", minimum={number(minimum)}" + (", exclusive=.true." if exclusive else "")
    if maximum is not None:
        options += f", maximum={number(maximum)}"
    call = f"{'reals' if count else 'real'}_field('{name}', {target}, {fortran_text(allowed)}, '{units}'{options})"
    return f"absolute_temperature({call})" if temperature else call


def is_kelvin(units, d):
    """A field in kelvin, whose small values --help's reader flags as degrees Celsius (a nondimensional
    model's temperatures, in units of 1, are not)."""
    return units == d.temperature_units == "K"


def initial_fields(d):
    """(name, component default (a list: an array field), units, bounds (bounds_text's arguments), meaning, is a
    temperature) of &initial: the columns of z, then a temperature per subsystem or the initial_thermal_field."""
    fields = [(c.name, c.initial, c.units, (c.minimum, c.exclusive, c.maximum, c.exclusive), c.meaning, False)
              for c in d.columns]
    if d.thermal_field:
        variable, field_name, values, meaning = d.thermal_field
        if len(values) != len(d.subsystems):
            raise DescriptionError(f"initial_thermal_field {field_name}: {len(values)} values for "
                                   f"{len(d.subsystems)} subsystems")
        units = {"entropy": d.entropy_units, "temperature": d.temperature_units,
                 "internal_energy": d.energy_units}[variable]
        bounds = (0.0, True, None) if variable != "entropy" else (None, False, None)
        return fields + [(field_name, values, units, bounds, meaning, variable == "temperature" and is_kelvin(units, d))]
    thermal = [part for part in d.subsystems if part.thermal]      # a mechanical subsystem has no temperature
    missing = [part.name for part in thermal if part.initial_temperature is None]
    if missing:
        raise DescriptionError(f"subsystems {missing} have no initial_temperature and the model no "
                               "initial_thermal_field")
    fields += [(f"theta_{part.name}", part.initial_temperature, d.temperature_units, (0.0, True, None),
                f"the temperature of {part.meaning}, whatever the thermodynamic variable",
                is_kelvin(d.temperature_units, d)) for part in thermal]
    return fields


def initial_variable(d):
    """The thermodynamic variable &initial gives the subsystems' state in."""
    return d.thermal_field[0] if d.thermal_field else "temperature"


def default_text(default):
    """A field's default in docs/input.md: 1.5, 3."""
    return ", ".join(f"{value:g}" for value in default) if isinstance(default, list) else f"{default:g}"


def scene_module(symbolic, source):
    d = symbolic.d
    name = d.name
    model_rows = [f"      table = [text_field('model_name', self%model_name, \"the model: '{name}'\", {name}_name)"]
    for p in d.parameters:
        bounds = (p.minimum, p.exclusive, p.maximum)
        call = real_field_call(p.name, f"self%parameters%{p.name}", bounds,
                               allowed_text(bounds_text(*bounds), p.units, p.meaning), p.units,
                               is_kelvin(p.units, d))
        model_rows.append(f"               {call}")
    initial = initial_fields(d)
    initial_rows = []
    for field_name, default, units, bounds, meaning, temperature in initial:
        count = len(default) if isinstance(default, list) else 0
        words = allowed_text(bounds_text(*bounds), units, meaning)
        if count:
            words = f"{count} " + words.replace("a real number", "real numbers", 1)
        call = real_field_call(field_name, f"self%{field_name}", bounds, words, units, temperature, count)
        initial_rows.append(f"      {'table = [' if not initial_rows else '         '}{call}")

    def join(rows, indent_first):
        out = []
        for k, row in enumerate(rows):
            end = "]" if k == len(rows) - 1 else ", &"
            out.append(wrap(row.strip() + end, indent_first if k == 0 else indent_first + 4))
        return out

    components = [f"    real(real64) :: {field_name}({len(default)}) = [{', '.join(map(number, default))}]  !! [{units}]"
                  if isinstance(default, list) else f"    real(real64) :: {field_name} = {number(default)}  !! [{units}]"
                  for field_name, default, units, *_ in initial]
    variable = initial_variable(d)
    domain = d.initial_domain or f"a state in the domain of the potentials of src/model/{name}/description.py"
    field_imports = sorted({"group_field", "real_field", "text_field"}
                           | ({"absolute_temperature"} if any(f[5] for f in initial) or any(
                               is_kelvin(p.units, d) for p in d.parameters) else set())
                           | ({"reals_field"} if any(isinstance(f[1], list) for f in initial) else set()),
                           key=["group_field", "real_field", "reals_field", "text_field", "absolute_temperature"].index)
    initial_vector = ", ".join(f"self%{field_name}" for field_name, *_ in initial)
    listing = " // &\n".join(f"      '{',' if k else ''} {field_name} = '//reals_text([self%{field_name}])"
                             for k, (field_name, *_) in enumerate(initial))
    PRINTER.owner = "self%parameters"
    theta_r = fortran(d.theta_r) if d.theta_r is not None else "300.0_real64"
    text = f"""{header(d, source, f"The input of {d.title} ({d.reference}):")}
!> &model (model_name = '{name}' and the parameters of the description) and &initial (the state, each subsystem's
!> temperature whatever the run's thermodynamic variable), as field tables; no constraints.
module {name}_scene
  use, intrinsic :: iso_fortran_env, only: real64
  use namelist_text, only: namelist_item
  use namelist_field, only: {", ".join(field_imports)}
  use namelist_group, only: read_group, value_origin
  use number_text, only: reals_text
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use model_scene, only: scene
  use failures, only: failure_none, failure_type, fail, failure_input, failure_code_name
  use thermo_variable_kinds, only: tau_{variable}
  use {name}_potential, only: {name}_parameters
  use {name}_model, only: make_{name}
  implicit none (type, external)
  private
  public :: {name}_name, new_{name}_scene

  character(len=*), parameter :: {name}_name = '{name}'

  !> The values of the two groups, in their namelist names.
  type, extends(scene) :: {name}_input
    character(len=24) :: model_name = {name}_name
    type({name}_parameters) :: parameters
{lines_of(components)}
  contains
    procedure :: group_names
    procedure :: fields
    procedure :: read
    procedure :: build
    procedure :: default_theta_r
    procedure :: constraint_count
  end type {name}_input

contains

  !> A scene of {name} with the defaults (the model registry's maker).
  subroutine new_{name}_scene(made)
    class(scene), allocatable, intent(out) :: made

    allocate ({name}_input :: made)
  end subroutine new_{name}_scene

  !> &model, &initial.
  pure subroutine group_names(self, names)
    class({name}_input), intent(in) :: self
    character(len=16), allocatable, intent(out) :: names(:)

    names = [character(len=16) :: 'model', 'initial']
  end subroutine group_names

  !> The fields of one group (docs/input.md).
  function fields(self, group) result(table)
    class({name}_input), intent(in), target :: self
    character(len=*), intent(in) :: group
    type(group_field), allocatable :: table(:)

    select case (group)
    case ('model')
{lines_of(join(model_rows, 3))}
    case ('initial')
{lines_of(join(initial_rows, 3))}
    case default
      allocate (table(0))
    end select
  end function fields

  !> Reads &model and &initial; the initial state must lie in the model's domain.
  subroutine read(self, text, origin, extra, failure)
    class({name}_input), intent(inout), target :: self
    character(len=*), intent(in) :: text, origin
    type(namelist_item), intent(in) :: extra(:)
    type(failure_type), intent(out) :: failure
    class(generic_model), allocatable :: model
    real(real64), allocatable :: z0(:)
    integer :: stat

    call read_group(text, 'model', self%fields('model'), origin, failure, extra)
    if (failure%failed()) return
    call read_group(text, 'initial', self%fields('initial'), origin, failure, extra)
    if (failure%failed()) return
    ! Refused here, where the input's origin is known (build knows no file).
    call initial_state(self, tau_{variable}, model, z0, stat)
    if (stat /= failure_none) call fail(failure, failure_input, value_origin(text, 'initial', '{initial[-1][0]}', &
      origin, extra)//': &initial: the state'// &
{listing} &
      //' is not allowed ('//failure_code_name(stat)//'); allowed: '// &
{wrap(fortran_text(domain) + ", '" + initial[-1][0] + "')", 3)}
  end subroutine read

  !> The model in thermodynamic variable `variable` and the initial state (no constraints).
  subroutine build(self, variable, model, z0, constraints, failure)
    class({name}_input), intent(in) :: self
    integer, intent(in) :: variable
    class(generic_model), allocatable, intent(out) :: model
    real(real64), allocatable, intent(out) :: z0(:)
    type(constraint_slot), allocatable, intent(out) :: constraints(:)
    type(failure_type), intent(out) :: failure
    integer :: stat

    allocate (constraints(0))
    call initial_state(self, variable, model, z0, stat)
    if (stat /= failure_none) call fail(failure, stat, '&initial: the initial state lies outside the model''s domain', &
                                        '&initial')
  end subroutine build

  ! The model in thermodynamic variable `variable` and the initial state, given in the {variable.replace("_", " ")}
  ! variable; stat a domain code if that state lies outside the model's domain.
  subroutine initial_state(self, variable, model, z0, stat)
    class({name}_input), intent(in) :: self
    integer, intent(in) :: variable
    class(generic_model), allocatable, intent(out) :: model
    real(real64), allocatable, intent(out) :: z0(:)
    integer, intent(out) :: stat
    class(generic_model), allocatable :: as_given

    allocate (as_given, source=make_{name}(self%parameters, tau_{variable}))
    allocate (model, source=make_{name}(self%parameters, variable))
    allocate (z0(model%state_size))
    call as_given%convert_state([{initial_vector}], model, z0, stat)
  end subroutine initial_state

  !> theta_R as the description states it.
  pure function default_theta_r(self) result(theta_r)
    class({name}_input), intent(in) :: self
    real(real64) :: theta_r

    theta_r = {theta_r}
  end function default_theta_r

  !> None: the model takes no constraints.
  pure integer function constraint_count(self)
    class({name}_input), intent(in) :: self

    constraint_count = 0
  end function constraint_count

end module {name}_scene
"""
    return tidy(text)


def input_rows(description, source):
    """The description's rows of docs/input.md's table (the same fields as --help)."""
    d = description
    rows = [f"| `&model` (`{d.name}`) | `model_name = '{d.name}'` | - | | {d.title} ({d.reference}), generated from "
            f"`{source}`: no `&constraints` group |"]
    for p in d.parameters:
        rows.append(f"| | `{p.name}` | {p.units} | {p.default:g} | {bounds_text(p.minimum, p.exclusive, p.maximum)}: "
                    f"{p.meaning} |")
    for k, (field_name, default, units, bounds, meaning, _) in enumerate(initial_fields(d)):
        group = f" `&initial` (`{d.name}`) " if k == 0 else " "
        shape = f"({len(default)})" if isinstance(default, list) else ""
        rows.append(f"|{group}| `{field_name}{shape}` | {units} | {default_text(default)} | {bounds_text(*bounds)}: "
                    f"{meaning} |")
    return "\n".join(rows)


# ---------------------------------------------------------------------------------- an element (potential_only)

POSITIVE_LOG = sp.Function("positive_log")      # a log whose argument is known positive: printed as log, not guarded


def element_guards(expressions, indent, positive):
    """guards() less the logs whose argument is positive wherever the positive invariants are (log(C/l0^2) after
    C > 0): the element's kernels run on every Newton iteration."""
    PRINTER.known_functions["positive_log"] = "log"
    assume = {x: sp.Dummy(positive=True) for x in positive}
    logs = {atom for e in expressions for atom in sp.sympify(e).atoms(sp.log)}
    marked = [sp.sympify(e).xreplace({atom: POSITIVE_LOG(atom.args[0]) for atom in logs
                                      if atom.args[0].subs(assume).is_positive}) for e in expressions]
    return guards(marked, indent, positive)


def element_module(description, source):
    """NAME_potential.f90 of a potential_only description: one type extending invariant_functions whose `kind`
    selects one of the element's kinds (the stored energies, then the subsystems) and `variable` the thermodynamic
    variable; values, gradients and Hessians, f(b) - f(a) free of cancellation, the temperature and tau from it,
    values with the temperature and rounding scales in one body, Gonzalez's parts between two states in one body
    (gonzalez_parts), the metric's scales, and the description's functions of the temperature. Subexpressions of
    the parameters alone are constants its maker computes once."""
    d = description
    name = d.name
    tau = sp.Symbol("tau", real=True)
    PRINTER.constant_names = {}
    constants = ParameterConstants([p.symbol for p in d.parameters])
    codes = {"domain_nonpositive_temperature", "domain_overflow"}
    kinds = []               # (label, invariants, {variable or None: (U, S, theta, tau_of_theta)}, scales by variable)
    for part, energy in d.stored_energies:
        invariants = [inv.symbol for inv in part.invariants]
        kinds.append((part, invariants, {None: (energy, sp.Float(0.0), None, None)},
                      {None: [inv.scale for inv in part.invariants]}))
    for part in d.subsystems:
        forms = thermodynamics(part)
        kinds.append((part, [inv.symbol for inv in part.invariants] + [tau], forms,
                      {v: [inv.scale for inv in part.invariants] + [part.tau_scales[v]] for v in THERMO_VARIABLES}))
    routines = ("evaluate", "values", "temperature", "inverse", "difference", "gonzalez")
    bodies = {routine: [] for routine in routines}
    temporaries = {routine: [0] for routine in routines}
    locals_ = {routine: [] for routine in routines}

    def keep_locals(routine, names):
        locals_[routine] += [n for n in names if n not in locals_[routine]]

    def body_of(routine, indent, invariants, positive, source_name, targets, values, optional=None, check_on=None):
        """Unpacked invariants, the domain checks of `check_on`, shared roots and the assignments (with `optional`
        (flag, targets, values): a second body with them when the flag is present)."""
        values = [constants.fold(sp.sympify(e)) for e in values]
        more = [constants.fold(sp.sympify(e)) for e in optional[2]] if optional else []
        check, _, _ = element_guards(check_on if check_on is not None else values, indent, positive)
        roots, (values, more) = shared_roots(positive, values, more)
        used = set().union(*(e.free_symbols for e in values + more + [p for _, p in roots]), set(positive))
        names = [x.name for x in invariants]
        keep_locals(routine, [n for n in names if n in {s.name for s in used}] + [root.name for root, _ in roots])
        lines = unpack(used, names, source_name, indent) + check
        lines += [wrap(f"{root.name} = {fortran(power)}", indent) for root, power in roots]
        if optional and more:
            lines += [INDENT*indent + f"if (present({optional[0]})) then"]
            lines += assignments(targets + optional[1], values + more, indent + 1, temporaries[routine])
            lines += [INDENT*indent + "else"] + assignments(targets, values, indent + 1, temporaries[routine])
            lines += [INDENT*indent + "end if"]
        else:
            lines += assignments(targets, values, indent, temporaries[routine])
        return lines

    for part, invariants, forms, _ in kinds:
        positive = [inv.symbol for inv in part.invariants if inv.positive]
        codes |= {"domain_nonpositive_length"} if positive else set()
        per_variable = {routine: [] for routine in routines}
        for variable, (u, s, temperature, tau_of_theta) in forms.items():
            indent = 3 if variable is None else 4
            values = [u, s]
            grads = [(i, k, sp.diff(f, x)) for k, f in enumerate(values) for i, x in enumerate(invariants)]
            hessians = [(i, j, k, sp.diff(f, x, y)) for k, f in enumerate(values)
                        for i, x in enumerate(invariants) for j, y in enumerate(invariants)]
            every_grad, every_hessian = grads, hessians      # gonzalez_parts writes their zeros too (no zeroing pass)
            grads = [g for g in grads if g[-1] != 0]
            hessians = [h for h in hessians if h[-1] != 0]
            per_variable["evaluate"].append((variable, body_of(
                "evaluate", indent, invariants, positive, "x",
                ["f(1)", "f(2)"] + [f"grad({i + 1}, {k + 1})" for i, k, _ in grads], values + [g for *_, g in grads],
                ("hess", [f"hess({i + 1}, {j + 1}, {k + 1})" for i, j, k, _ in hessians], [h for *_, h in hessians]),
                check_on=values)))
            at_a = {x: sp.Symbol(f"{x.name}_a", real=True) for x in invariants}
            at_b = {x: sp.Symbol(f"{x.name}_b", real=True) for x in invariants}
            delta = {x: sp.Symbol(f"d_{x.name}", real=True) for x in invariants}
            differences = [difference(value, at_a, at_b, delta) for value in values]
            ends = [e.subs(at, simultaneous=True) for at in (at_a, at_b) for e in values]
            ends_positive = [at[x] for at in (at_a, at_b) for x in positive]
            names_here = [n for x in invariants for n in (at_a[x].name, at_b[x].name, delta[x].name)]
            unpacked = [INDENT*indent + f"{at_a[x].name} = a({i + 1})" for i, x in enumerate(invariants)]
            unpacked += [INDENT*indent + f"{at_b[x].name} = b({i + 1})" for i, x in enumerate(invariants)]
            unpacked += [INDENT*indent + f"{delta[x].name} = b({i + 1}) - a({i + 1})" for i, x in enumerate(invariants)]

            def with_ends(routine, lines, names):
                """The lines after the unpacking of the end points' names (of `names`) they use."""
                words = set(re.findall(r"[A-Za-z_][A-Za-z_0-9]*", "\n".join(lines)))
                keep_locals(routine, [n for n in names if n in words])
                return [line for line in unpacked if line.split()[0] in words] + lines

            per_variable["difference"].append((variable, with_ends("difference", body_of(
                "difference", indent, [], ends_positive, "", ["delta(1)", "delta(2)"], differences, check_on=ends),
                names_here)))
            # Gonzalez's parts in one body: grad f(m), f(b) - f(a) and, for the Jacobian, the Hessian at m and grad f(b).
            at_m = {x: sp.Symbol(f"{x.name}_m", real=True) for x in invariants}
            mid_positive = [at_m[x] for x in positive]
            gonzalez = body_of("gonzalez", indent, [], ends_positive + mid_positive, "",
                               ["delta(1)", "delta(2)"] + [f"grad_m({i + 1}, {k + 1})" for i, k, _ in every_grad],
                               differences + [g.subs(at_m, simultaneous=True) for *_, g in every_grad],
                               ("hess_m", [f"hess_m({i + 1}, {j + 1}, {k + 1})" for i, j, k, _ in every_hessian]
                                + [f"grad_b({i + 1}, {k + 1})" for i, k, _ in every_grad],
                                [h.subs(at_m, simultaneous=True) for *_, h in every_hessian]
                                + [g.subs(at_b, simultaneous=True) for *_, g in every_grad]),
                               check_on=ends + [e.subs(at_m, simultaneous=True) for e in values])
            unpacked += [INDENT*indent + f"{at_m[x].name} = 0.5_real64*(a({i + 1}) + b({i + 1}))"
                         for i, x in enumerate(invariants)]
            per_variable["gonzalez"].append((variable, with_ends("gonzalez", gonzalez,
                                                                 names_here + [at_m[x].name for x in invariants])))
            if variable is None:        # no thermodynamic variable: no temperature, the values' scales |U|
                per_variable["values"].append((variable, body_of(
                    "values", indent, invariants, positive, "x", ["f(1)", "f(2)"], values,
                    ("scales", ["scales(1)", "scales(2)"], [sp.Abs(u, evaluate=False), sp.Float(0.0)]))))
                per_variable["temperature"].append((variable, [INDENT*indent + "stat = domain_overflow"]))
                per_variable["inverse"].append((variable, [INDENT*indent + "stat = domain_overflow"]))
                continue
            at_theta = {tau: sp.Symbol("theta", positive=True)}
            scales = [rounding_scale(sp.sympify(value).subs(at_theta)) for value in forms["temperature"][:2]]
            theta_symbol = sp.Symbol("theta", positive=True)
            scales = [e.subs(theta_symbol, temperature) for e in scales]
            per_variable["values"].append((variable, body_of(
                "values", indent, invariants, positive, "x", ["f(1)", "f(2)", "theta"], values + [temperature],
                ("scales", ["scales(1)", "scales(2)"], scales), check_on=values + [temperature])
                + [INDENT*indent + "if (.not. (theta > 0.0_real64)) stat = domain_nonpositive_temperature"]))
            per_variable["temperature"].append((variable, body_of(
                "temperature", indent, invariants, positive, "x", ["theta"], [temperature])))
            per_variable["inverse"].append((variable, body_of(
                "inverse", indent, invariants[:-1], positive, "mechanical", ["tau"], [tau_of_theta])))
        for routine in routines:
            bodies[routine].append((part, per_variable[routine]))

    def cases(routine):
        lines = [INDENT*2 + "select case (self%kind)"]
        for k, (part, by_variable) in enumerate(bodies[routine]):
            lines.append(INDENT*2 + f"case ({k + 1})  ! {part.meaning}")
            if by_variable[0][0] is None:
                lines += by_variable[0][1]
                continue
            lines.append(INDENT*3 + "select case (self%variable)")
            for variable, body in by_variable:
                lines += [INDENT*3 + f"case (tau_{variable})"] + body
            lines.append(INDENT*3 + "end select")
        return lines + [INDENT*2 + "end select"]

    def declaration(routine, extra=()):
        return declare(locals_[routine] + [f"t_{i}" for i in range(1, temporaries[routine][0] + 1)] + list(extra), 2)

    theta = TEMPERATURE
    functions = []
    for function, meaning, value in d.temperature_functions:
        folded = constants.fold(value.subs(theta, sp.Symbol("theta", positive=True)))
        logarithmic_derivative = sp.simplify(sp.diff(value, theta)/value).subs(theta, sp.Symbol("theta", positive=True))
        functions.append(f"""
  !> {meaning}, and optionally the derivative of its reciprocal d(1/value)/dtheta.
  pure subroutine {function}(self, theta, value, dinverse_dtheta)
    class({name}_potentials), intent(in) :: self
    real(real64), intent(in) :: theta
    real(real64), intent(out) :: value
    real(real64), intent(out), optional :: dinverse_dtheta

{wrap(f"value = {fortran(folded)}", 2)}
{wrap(f"if (present(dinverse_dtheta)) dinverse_dtheta = {fortran(constants.fold(-logarithmic_derivative))}/value", 2)}
  end subroutine {function}""")

    largest = max(len(invariants) for _, invariants, _, _ in kinds)
    maker = ["    element%parameters = parameters", "    element%kind = kind", "    element%variable = variable",
             "    select case (kind)"]
    PRINTER.owner = "parameters"
    for k, (part, invariants, _, scales) in enumerate(kinds):
        maker += [f"    case ({k + 1})  ! {part.meaning}", f"      element%invariant_count = {len(invariants)}"]
        if None in scales:
            maker.append(wrap(f"element%metric_scale(1:{len(invariants)}) = [" + ", ".join(map(fortran, scales[None]))
                              + "]", 3))
            continue
        maker.append("      select case (variable)")
        for variable in THERMO_VARIABLES:
            maker += [f"      case (tau_{variable})", wrap(f"element%metric_scale(1:{len(invariants)}) = ["
                                                         + ", ".join(map(fortran, scales[variable])) + "]", 4)]
        maker.append("      end select")
    maker.append("    end select")
    maker += [wrap(f"element%constants({k + 1}) = {fortran(value)}", 2) for k, value in enumerate(constants.values)]
    PRINTER.owner = "self%parameters"
    parameter_type = [f"  !> The element's data (src/model/{name}/description.py).", f"  type :: {name}_parameters"]
    parameter_type += [f"    real(real64) :: {p.name} = {number(p.default)}  !! {p.meaning} [{p.units}]"
                       for p in d.parameters]
    parameter_type.append(f"  end type {name}_parameters")
    kind_words = "\n".join(f"!>  {k + 1}: {part.meaning}" for k, (part, *_) in enumerate(kinds))
    text = f"""{header(d, source, f"The potentials of {d.title} ({d.reference}),")}
!> an element another model's code assembles (potential_only): (U, S) of its kinds in their invariants, with
!> gradients and Hessians in each thermodynamic variable (entropy, temperature, internal energy), f(b) - f(a) free
!> of cancellation, the temperature of eq. (2), tau from a temperature, the metric's scales and functions of the
!> temperature, in closed form; subexpressions of the data alone are constants the maker computes once. Kinds:
{kind_words}
module {name}_potential
  use, intrinsic :: iso_fortran_env, only: real64
  use invariant_function, only: invariant_functions
  use failures, only: failure_none, {", ".join(sorted(codes))}
  use thermo_variable_kinds, only: tau_entropy, tau_temperature, tau_internal_energy
  use special_functions, only: log1p, expm1
  implicit none (type, external)
  private
  public :: {name}_parameters, {name}_potentials, make_{name}_potentials

{lines_of(parameter_type)}

  !> (U, S) of one element of kind `kind` (numbered as above) in thermodynamic variable `variable`.
  type, extends(invariant_functions) :: {name}_potentials
    type({name}_parameters) :: parameters
    integer :: kind = 1
    integer :: variable = tau_entropy
    integer :: invariant_count = 1  !! the kind's invariants (tau last)
    real(real64) :: metric_scale({largest}) = 1.0_real64  !! their typical sizes, for the metric
    real(real64) :: constants({max(len(constants.values), 1)}) = 0.0_real64  !! of the data alone
  contains
    procedure :: evaluate
    procedure :: difference
    procedure :: gonzalez_parts
    procedure :: temperature
    procedure :: values_and_temperature
    procedure :: tau_from_temperature{"".join(chr(10) + f"    procedure :: {function}" for function, *_ in d.temperature_functions)}
  end type {name}_potentials

  ! Largest argument of exp that stays finite, with a margin.
  real(real64), parameter :: max_exponent = 0.9_real64*log(huge(1.0_real64))

contains

  !> The element of kind `kind` with data `parameters` in thermodynamic variable `variable` (tau_*).
  pure function make_{name}_potentials(parameters, kind, variable) result(element)
    type({name}_parameters), intent(in) :: parameters
    integer, intent(in) :: kind, variable
    type({name}_potentials) :: element

{lines_of(maker)}
  end function make_{name}_potentials

  !> f = (U, S), their gradients in the invariants (tau last) and optionally their Hessians.
{procedure_head("evaluate", name)}
{lines_of(declaration("evaluate"))}

    grad = 0.0_real64
    if (present(hess)) hess = 0.0_real64
    stat = failure_none
{lines_of(cases("evaluate"))}
  end subroutine evaluate

  !> f(b) - f(a) without cancellation (generate_model.py's `difference`: log1p, expm1, factored powers).
{procedure_head("difference", name)}
{lines_of(declaration("difference"))}

    stat = failure_none
{lines_of(cases("difference"))}
  end subroutine difference

  !> The parts of Gonzalez's discrete gradient between a and b (src/scheme/discrete_gradient's gonzalez_from_parts)
  !> in one body, their common subexpressions shared: grad f at m = (a + b)/2, f(b) - f(a) free of cancellation
  !> and, for its Jacobian, the Hessian at m and grad f(b) (both or neither). Every entry of the kind's invariants is
  !> written, its zeros too (no pass that zeroes the arrays first: it cost about a fifth of the call); a larger array's
  !> entries beyond them are not, nor any output after a domain error (stat /= failure_none). Contiguous arrays: a
  !> caller's section would be packed (docs/performance.md, Issue 42).
  pure subroutine gonzalez_parts(self, a, b, grad_m, delta, stat, hess_m, grad_b)
    class({name}_potentials), intent(in) :: self
    real(real64), intent(in), contiguous :: a(:), b(:)
    real(real64), intent(out), contiguous :: grad_m(:, :), delta(:)
    integer, intent(out) :: stat
    real(real64), intent(out), optional, contiguous :: hess_m(:, :, :), grad_b(:, :)
{lines_of(declaration("gonzalez"))}

    stat = failure_none
{lines_of(cases("gonzalez"))}
  end subroutine gonzalez_parts

  !> Theta = d_tau U / d_tau S of eq. (2) in closed form (a kind without tau has none: domain_overflow).
{procedure_head("temperature", name)}
{lines_of(declaration("temperature"))}

    theta = 0.0_real64
    stat = failure_none
{lines_of(cases("temperature"))}
    if (stat == failure_none .and. .not. (theta > 0.0_real64)) stat = domain_nonpositive_temperature
  end subroutine temperature

  !> (U, S), the temperature (0 for a kind without tau) and optionally the values' rounding scales (the thermal
  !> kinds' by generate_model.py's `rounding_scale`, the sizes of the terms each is summed from; |U| otherwise).
{procedure_head("values_and_temperature", name)}
{lines_of(declaration("values"))}

    theta = 0.0_real64
    stat = failure_none
{lines_of(cases("values"))}
  end subroutine values_and_temperature

  !> tau at the mechanical invariants `mechanical` and the temperature theta (> 0); a kind without tau has none
  !> (domain_overflow).
{procedure_head("tau_from_temperature", name)}
{lines_of(declaration("inverse"))}

    tau = 0.0_real64
    stat = failure_none
    if (.not. (theta > 0.0_real64)) then
      stat = domain_nonpositive_temperature
      return
    end if
{lines_of(cases("inverse"))}
  end subroutine tau_from_temperature
{"".join(functions)}

end module {name}_potential
"""
    return tidy(text)


def refuse_name_clashes(files):
    """A DescriptionError if a generated procedure declares a name twice or after an intrinsic (fortran_names):
    a name of the description clashes with one the generator writes."""
    for file, text in files.items():
        clashes = name_clashes(text)
        if clashes:
            procedure, name, other = clashes[0]
            raise DescriptionError(f"the name {name} clashes in the generated {file} (procedure {procedure}) with "
                                   f"{other} (Fortran ignores case); allowed: names that are neither an intrinsic "
                                   "(exp, log, sqrt, ...) nor one the generator writes (x, f, grad, hess, stat, z, "
                                   "partials, theta, tau, t_1, ..., and the names it derives from yours)")


def main(arguments=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("description")
    parser.add_argument("--output", help="the folder of the generated files (default: the description's)")
    parser.add_argument("--input-rows", action="store_true", help="print the rows of docs/input.md")
    options = parser.parse_args(arguments)
    path = Path(options.description)
    try:
        source = path.resolve().relative_to(Path(__file__).resolve().parents[3]).as_posix() \
            if Path(__file__).resolve().parents[3] in path.resolve().parents else path.as_posix()
        files = {}
        for description in load(path):
            PRINTER.parameter_names = {p.name for p in description.parameters}
            if options.input_rows:
                if description.scene:
                    print(input_rows(description, source))
                continue
            if description.potential_only:
                files[f"{description.name}_potential.f90"] = element_module(description, source)
                continue
            if isinstance(description, ChainDescription):
                from chain_blocks import blocks_module    # it prints with this module's helpers
                files[f"{description.name}_blocks.f90"] = blocks_module(description, source)
                continue
            symbolic = SymbolicModel(description)
            files[f"{description.name}_potential.f90"] = (mechanical_potential_module if symbolic.mechanical
                                                          else potential_module)(symbolic, source)
            files[f"{description.name}_model.f90"] = model_module(symbolic, source)
            if description.scene:
                files[f"{description.name}_scene.f90"] = scene_module(symbolic, source)
        if options.input_rows:
            return 0
        refuse_name_clashes(files)
    except DescriptionError as error:
        print(f"generate_model.py: {path}: {error}", file=sys.stderr)
        return 2
    output = Path(options.output) if options.output else path.parent
    output.mkdir(parents=True, exist_ok=True)
    for name, text in files.items():
        (output / name).write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
