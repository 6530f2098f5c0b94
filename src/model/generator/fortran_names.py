"""The names a generated Fortran procedure declares, checked before a file is written: a name of a description
(an invariant, a column, a parameter) becomes a local of the procedures that use it, beside the names the
generator writes itself (x, f, grad, hess, stat, z, partials, t_1, ..., d_C, du_a_dC, ...). Fortran ignores case,
so `C` and `c` are one name, and a local named as an intrinsic the code calls (exp, log, sqrt) hides it. Without
this check such a description gave Fortran that does not compile ("Symbol 'x' already has basic type of REAL")."""
import re

# The intrinsics and special functions the generated code may call.
CALLED_INTRINSICS = {
    "abs", "all", "allocated", "any", "count", "epsilon", "exp", "expm1", "huge", "int", "log", "log1p", "matmul",
    "max", "merge", "min", "nint", "present", "real", "sign", "size", "sqrt", "sum", "tiny", "transpose"}
_PROCEDURE = re.compile(r"^[ \t]*(?:(?:pure|elemental|impure|recursive|module)[ \t]+)*(subroutine|function)[ \t]+(\w+)"
                        r"[ \t]*\(([^)]*)\)(.*?)^[ \t]*end[ \t]+\1[ \t]+\2\b", re.M | re.S | re.I)
_DECLARATION = re.compile(r"^[ \t]*(?:real\(real64\)|integer(?:\(\w+\))?|logical|type\(\w+\)|class\(\w+\)|"
                          r"character\([^)]*\)|procedure\([^)]*\))[^!\n]*?::(.*)$", re.M | re.I)


def _entity_names(entities):
    """The names of a declaration's entity list (`a(3), b = [1, 2], c`): its commas outside brackets split it."""
    names, depth, start = [], 0, 0
    for i, character in enumerate(entities + ","):
        if character in "([":
            depth += 1
        elif character in ")]":
            depth -= 1
        elif character == "," and depth == 0:
            match = re.match(r"\s*(\w+)", entities[start:i])
            if match:
                names.append(match.group(1))
            start = i + 1
    return names


def name_clashes(text):
    """(procedure, name, what it clashes with) for every name a procedure of the Fortran `text` declares twice in
    any case (its dummy arguments and its locals, before any `contains`) or names after an intrinsic it may call."""
    joined = re.sub(r"&[ \t]*\n[ \t]*&?", " ", re.sub(r"!.*$", "", text, flags=re.M))
    clashes = []
    for match in _PROCEDURE.finditer(joined):
        procedure, arguments, body = match.group(2), match.group(3), match.group(4)
        body = re.split(r"^[ \t]*contains[ \t]*$", body, maxsplit=1, flags=re.M | re.I)[0]
        dummies = [name.strip() for name in arguments.split(",") if name.strip()]
        declared = [name for entities in _DECLARATION.findall(body) for name in _entity_names(entities)]
        clashes += [(procedure, name, f"the intrinsic {name.lower()}") for name in declared
                    if name.lower() in CALLED_INTRINSICS]
        # a dummy argument is declared once in the body; a local must differ from every other name
        seen = {name.lower(): f"the dummy argument {name}" for name in dummies}
        dummy_declared = set()
        for name in declared:
            key = name.lower()
            if key in seen and seen[key].startswith("the dummy argument") and key not in dummy_declared:
                dummy_declared.add(key)
                continue
            if key in seen:
                clashes.append((procedure, name, seen[key]))
            else:
                seen[key] = f"the local {name}"
    return clashes
