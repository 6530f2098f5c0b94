"""The integrators as the code's registry describes them (src/integrator/integrator_registry),
read from the files the code writes: a study index's /integrators table, or a run file's
scheme, scheme_label and scheme_family attributes. The figures take the schemes' names, their
order and their colours from here, so that a new integrator needs no change in the scripts.
"""

# Colours by position in the registry (the first five are those the gallery has always used);
# as many as the registry has integrators, so that no two share a colour.
PALETTE = ("tab:red", "tab:blue", "tab:cyan", "tab:green", "tab:purple", "tab:orange", "tab:brown",
           "tab:pink", "tab:olive", "tab:gray", "navy", "goldenrod", "black", "lime", "teal", "maroon",
           "darkviolet", "sienna", "crimson", "darkkhaki", "slateblue", "darkcyan")

_KNOWN = {}     # name -> {"position": int, "label": str, "family": str, "adaptive": bool, "error_control": bool}
_REGISTRY_SIZE = [0]    # integrators of the last index registered
# A scheme with error control run with a tolerance (EME and the midpoint rule then choose their
# steps, the fixed-step relaxed schemes check gamma) is a curve of its own: its name carries this
# suffix and its label "-tol".
TOLERANCE_SUFFIX = "+tolerance"


def _text(value):
    return value.decode() if isinstance(value, bytes) else str(value)


def register_index(handle):
    """Registers the integrators of an open study index (h5py File), if it has /integrators."""
    if "integrators" not in handle:
        return
    table = handle["integrators"][()]
    for position, row in enumerate(table):
        flags = {flag: bool(row[flag]) if flag in table.dtype.names else False
                 for flag in ("adaptive", "error_control")}
        _KNOWN[_text(row["name"])] = {"position": position, "label": _text(row["label"]),
                                      "family": _text(row["family"]), **flags}
    _REGISTRY_SIZE[0] = len(table)


def tolerance_variant(name):
    """The name of `name` run with a tolerance: itself if the tolerance changes nothing about how
    it is named (an adaptive scheme, or one without error control), else a variant placed after
    every registered integrator (in the base's order), labelled LABEL-tol."""
    known = _KNOWN.get(name)
    if known is None or known.get("adaptive") or not known.get("error_control"):
        return name
    variant = name + TOLERANCE_SUFFIX
    _KNOWN.setdefault(variant, {**known, "position": _REGISTRY_SIZE[0] + known["position"],
                                "label": known["label"] + "-tol"})
    return variant


def register_run(attrs):
    """Registers the integrator of one run file from its root attributes (a dict)."""
    name = _text(attrs["scheme"])
    if name not in _KNOWN and "scheme_label" in attrs:
        _KNOWN[name] = {"position": len(_KNOWN), "label": _text(attrs["scheme_label"]),
                        "family": _text(attrs.get("scheme_family", ""))}


def position(name):
    """The integrator's place in the registry (unknown names after every known one)."""
    return _KNOWN[name]["position"] if name in _KNOWN else len(_KNOWN)


def label(name):
    """The plain name the figures use (the paper's EME and MP, RK4, ...), or the name itself."""
    return _KNOWN[name]["label"] if name in _KNOWN else name


def colour(name):
    """The integrator's colour: by its place in the registry (tolerance variants after it)."""
    return PALETTE[position(name) % len(PALETTE)] if name in _KNOWN else "black"


# Colours by scheme family (the registry's `family`), Okabe-Ito, so that the study charts give one
# colour to a family and one marker to each scheme in it; titles for the family panels.
FAMILY_COLOURS = {"discrete_gradient_step": "#D55E00", "relaxation": "#0072B2", "petsc_ts": "#009E73",
                  "sundials_cvode": "#CC79A7"}
FAMILY_TITLES = {"discrete_gradient_step": "discrete-gradient steps (EME, midpoint rule)",
                 "relaxation": "relaxed Runge-Kutta", "petsc_ts": "PETSc TS", "sundials_cvode": "SUNDIALS CVODE"}
# One marker per scheme, by its place in the registry (tolerance variants after every integrator).
SCHEME_MARKERS = ("o", "s", "D", "^", "v", "<", ">", "p", "h", "X", "P", "*", "d", "H", "8")


def family(name):
    """The integrator's family in the registry ('' when unknown)."""
    return _KNOWN[name].get("family", "") if name in _KNOWN else ""


def family_colour(name):
    """The colour of the integrator's family (black for a family without one)."""
    return FAMILY_COLOURS.get(family(name), "black")


def family_title(name):
    """A family's title for a panel, or the family's own name."""
    return FAMILY_TITLES.get(name, name or "other")


def marker(name):
    """The integrator's marker: by its place in the registry."""
    return SCHEME_MARKERS[position(name) % len(SCHEME_MARKERS)]
