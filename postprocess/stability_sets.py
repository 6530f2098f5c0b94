"""The harder scene set of the stability study (make study; docs/performance.md): where each
integrator fails and why.

Four scenes, each a change of the paper's (inputs/study_stability_<scene>.nml and
..._tolerance.nml): a lower viscosity, stiffer springs, a higher conductivity and a larger
initial temperature gap, in the temperature variable on [0, 20] s. The fixed-step schemes run over
dt, the schemes that choose or check their steps over their tolerance (EME and the midpoint rule
with step-size control, the fixed-step relaxed schemes with the gamma band, relaxed_dp853, CVODE
and ts_rk5dp). A finished case is classified as in the paper-scene map (kept, energy, Lyapunov);
a failed one by why it failed (FAILURES, from the status the index holds).
"""
import numpy as np

import integrators
from plotting import DOUBLE_COLUMN, plt, save

SCENES = {"low_viscosity": "low viscosity", "stiff_spring": "stiff springs",
          "high_conductivity": "high conductivity", "temperature_gap": "temperature gap"}
# Why a case failed, matched in lower case against its status, in this order of precedence.
FAILURES = (
    ("gamma", ("relaxation root", "outside the band")),
    ("step budget", ("step-size underflow", "t_end not reached", "shrank below round-off",
                     "trial steps rejected", "rejected 100 times")),
    ("no root", ("no root", "diverged_nonlinear_solve", "newton", "did not converge")),
    ("domain", ("domain", "blow-up", "non-positive temperature", "nan")),
)
OUTCOMES = ("kept", "energy", "lyapunov", "nonphysical", "gamma", "step budget", "no root", "domain", "solver")
OUTCOME_TEXT = {
    "kept": "finished, everything kept", "energy": "finished, energy error > 1e-6",
    "lyapunov": "finished, V rose", "nonphysical": "finished, non-physical state",
    "gamma": "failed: relaxation (no gamma, or gamma outside its band)",
    "step budget": "failed: step-size underflow or step budget",
    "no root": "failed: no root (Newton)", "domain": "failed: left the model's domain",
    "solver": "failed: other solver failure (TS, CVODE)",
}
OUTCOME_COLOURS = {"kept": "#009E73", "energy": "#E69F00", "lyapunov": "#F0E442", "nonphysical": "#303030",
                   "gamma": "#CC79A7", "step budget": "#0072B2", "no root": "#56B4E9", "domain": "#7f7f7f",
                   "solver": "#D55E00"}


def failure_reason(status):
    """The FAILURES name of a failed case's status, or 'solver'."""
    text = status.lower()
    for name, markers in FAILURES:
        if any(marker in text for marker in markers):
            return name
    return "solver"


def outcome(row, classify, temperatures_positive):
    """The OUTCOMES name of one index row; classify and temperatures_positive are the paper-scene
    map's rules (study_analysis)."""
    if row["status"].startswith("failed"):
        return failure_reason(row["status"])
    name, _ = classify(row["status"], row["energy_drift"], row["max_lyapunov_increment"],
                       temperatures_positive(row["min_temperature"]))
    return name


def grid(rows, column, classify, temperatures_positive):
    """Outcome grid of one study: rows = schemes (registry order), columns = dt or tolerance."""
    keys = sorted({row["scheme"] for row in rows}, key=lambda name: (integrators.position(name), name))
    values = sorted({row[column] for row in rows}, reverse=(column == "tolerance"))
    codes = np.full((len(keys), len(values)), -1, dtype=int)
    cases = np.zeros(codes.shape, dtype=int)
    status = np.full(codes.shape, "", dtype=object)
    for row in rows:
        i, j = keys.index(row["scheme"]), values.index(row[column])
        codes[i, j] = OUTCOMES.index(outcome(row, classify, temperatures_positive))
        cases[i, j], status[i, j] = row["case"], row["status"]
    return {"keys": keys, "column": column, "values": np.array(values), "outcome": codes, "case": cases,
            "status": status}


def analyse(study_dir, read_index, classify, temperatures_positive):
    """{scene: {"fixed": grid over dt, "tolerance": grid over tolerance}} of every scene."""
    grids = {}
    for scene in SCENES:
        fixed = read_index(study_dir / f"stability_{scene}")
        controlled = read_index(study_dir / f"stability_{scene}_tolerance")
        grids[scene] = {"fixed": grid(fixed, "dt", classify, temperatures_positive),
                        "tolerance": grid(controlled, "tolerance", classify, temperatures_positive)}
    return grids


def draw_grid(ax, data, title):
    colours = [OUTCOME_COLOURS[name] for name in OUTCOMES]
    image = np.full(data["outcome"].shape + (3,), 1.0)
    for (i, j), code in np.ndenumerate(data["outcome"]):
        if code >= 0:
            image[i, j] = plt.matplotlib.colors.to_rgb(colours[code])
    ax.imshow(image, aspect="auto", interpolation="nearest")
    ax.set_yticks(range(len(data["keys"])), [integrators.label(name) for name in data["keys"]])
    ax.set_xticks(range(len(data["values"])), [f"{value:g}" for value in data["values"]], rotation=90)
    ax.set_xlabel("dt [s]" if data["column"] == "dt" else "tolerance")
    ax.set_title(title)
    ax.tick_params(length=0)


def figure(grids, output):
    """One row of two maps per scene: fixed steps over dt, step control over tolerance."""
    fig, axes = plt.subplots(len(grids), 2, figsize=(DOUBLE_COLUMN, 2.05 * len(grids) + 0.9),
                             gridspec_kw={"width_ratios": (10, 6)})
    for row, (scene, pair) in enumerate(grids.items()):
        draw_grid(axes[row, 0], pair["fixed"], f"{SCENES[scene]}: fixed steps")
        draw_grid(axes[row, 1], pair["tolerance"], f"{SCENES[scene]}: step control")
    used = sorted({code for pair in grids.values() for data in pair.values() for code in data["outcome"].ravel()
                   if code >= 0})
    handles = [plt.matplotlib.patches.Patch(color=OUTCOME_COLOURS[OUTCOMES[code]], label=OUTCOME_TEXT[OUTCOMES[code]])
               for code in used]
    fig.legend(handles=handles, loc="outside lower center", ncols=2)
    title = ("Stability over the harder scene set (temperature variable, [0, 20] s): the outcome of every "
             "scheme at every dt (fixed steps) and tolerance (step control), and why a failed case failed")
    return save(fig, output, title)


def findings(grids):
    """Plain lines: per scene and scheme, the settings it kept everything at, and each failure."""
    lines = []
    for scene, pair in grids.items():
        for kind, data in pair.items():
            for i, name in enumerate(data["keys"]):
                codes = data["outcome"][i]
                kept = [f"{v:g}" for v, code in zip(data["values"], codes) if code == 0]
                failures = {}
                for v, code in zip(data["values"], codes):
                    if code >= 0 and OUTCOMES[code] not in ("kept",):
                        failures.setdefault(OUTCOMES[code], []).append(f"{v:g}")
                text = "; ".join(f"{reason} at {', '.join(values)}" for reason, values in failures.items())
                lines.append(f"stability {SCENES[scene]} ({'dt' if kind == 'fixed' else 'tolerance'}) "
                             f"{integrators.label(name)}: kept at {len(kept)} of {(codes >= 0).sum()}"
                             + (f"; {text}" if text else ""))
    return lines


def write_summary(handle, grids, write_dataset):
    """One group per scene and kind in the summary file."""
    for scene, pair in grids.items():
        for kind, data in pair.items():
            g = handle.create_group(f"stability_set/{scene}/{kind}")
            g.attrs["description"] = (f"outcome of each case of stability_{scene}"
                                      + ("" if kind == "fixed" else "_tolerance")
                                      + " (figure study_stability_set); rows: scheme, columns: "
                                      + ("dt" if kind == "fixed" else "tolerance"))
            write_dataset(g, "scheme", [integrators.label(name) for name in data["keys"]], "1", "row: scheme")
            write_dataset(g, data["column"], data["values"], "s" if kind == "fixed" else "1", "column")
            write_dataset(g, "outcome", data["outcome"], "1", "index into outcome_names; -1: not run")
            write_dataset(g, "outcome_names", [OUTCOME_TEXT[name] for name in OUTCOMES], "1", "outcome classes")
            write_dataset(g, "case", data["case"], "1", "case number in the study's index.h5")
            write_dataset(g, "status", data["status"], "1", "status of the case in the index")
