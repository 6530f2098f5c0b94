"""Figures of the parameter studies (study_analysis.py): names, styles and the four figures.

A curve or map row is a scheme and thermodynamic variable pair, e.g. ("eme", "temperature"),
labelled in the paper's notation (EME_theta) with the label the integrator registry gives
(postprocess/integrators.py). Colour says the scheme's family (discrete-gradient steps, relaxed
Runge-Kutta, PETSc TS, CVODE), the marker the scheme, line style and fill the thermodynamic
variable (solid and filled: s; dashed and open, larger: theta; dotted and filled, smaller: u, so
that coinciding curves stay visible). The timing charts (work precision, structure against cost)
give each family a row of panels of its own with its legend beside it, the other families' curves
in light grey behind, on the same axes; work precision has a column of them per model (the
double pendulum, the gas containers), and the stability map a panel per scene. The figures use
the paper style of plotting.py; what each shows in detail (reference, fit rule, classification)
goes to its caption file and metadata.
"""
from pathlib import Path

import numpy as np
from matplotlib.colors import ListedColormap
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

import integrators
from plotting import DOUBLE_COLUMN, MIN_FONT_POINTS, plt, save, variable_position
from trajectory import VARIABLE_NAMES, VARIABLE_SYMBOLS

# Log axes cannot show 0: values below LOG_FLOOR (exact zeros included) are drawn at it. Relative
# energy round-off is ~1e-16 and an entropy round-off ~1e-16 J/K (S ~ 2 J/K), so 1e-17 sits below
# any computed non-zero value.
LOG_FLOOR = 1e-17
OUTCOME_TEXT = {
    "kept": "finished, everything kept (energy error <= 1e-6, V non-increasing, temperatures > 0)",
    "energy": "finished, energy error > 1e-6",
    "lyapunov": "finished, energy kept, V rose (max dV > 1e-8 J; gas containers: 1e-8, nondimensional)",
    "solver": "failed: no solution of a step (Newton divergence, no root, halving exhausted)",
    "nonphysical": "failed: non-physical state or blow-up",
}
OUTCOME_COLOURS = {"kept": "#009E73", "energy": "#E69F00", "lyapunov": "#F0E442",
                   "solver": "#56B4E9", "nonphysical": "#303030"}
NOT_RUN_COLOUR = "white"
SCENE_TITLES = {"paper": "paper scene", "hard": "harder scene", "gas": "gas containers",
                "gonzalez": "elastic (Gonzalez)", "romero": "Romero's\nthermoelastic"}
# The stability map's rows [in]: the scenes side by side, so that the map fits a page.
MAP_ROW_HEIGHT = 0.2
# The timing charts' time (study_analysis.py --time): the axis's words and the caption's account of it.
TIME_AXES = {
    "cpu": ("solve CPU time", "the CPU time of the case's process over its time loop (the index's "
            "solve_cpu_time_seconds), to which waiting for a core that other work holds does not add"),
    "wall": ("solve wall time", "the wall time of the case's time loop (the index's solve_time_seconds), which "
             "other work sharing the cores inflates"),
}


def key_rank(key):
    """Sort key of a (scheme, variable) pair: registry order, unknown names last."""
    scheme, variable = key
    return (integrators.position(scheme), scheme, variable_position(variable), variable)


def curve_keys(rows):
    """The (scheme, thermo_variable) pairs of index rows, each once, in study order."""
    return sorted({(row["scheme"], row["thermo_variable"]) for row in rows}, key=key_rank)


# The thermo_variable of a run without thermal unknowns (elastic springs): no subscript.
NO_VARIABLE = ("none", "")


def plain_name(scheme, variable):
    """EME_theta, MP_u, TS-midpoint_s, BDF2_theta, RK4_u; EME for elastic springs (no variable)."""
    if variable in NO_VARIABLE:
        return integrators.label(scheme)
    return f"{integrators.label(scheme)}_{VARIABLE_NAMES.get(variable, variable)}"


def label(scheme, variable):
    """The paper's notation with a subscript, for legends and axes (none without a variable)."""
    if variable in NO_VARIABLE:
        return integrators.label(scheme)
    return rf"{integrators.label(scheme)}$_{{{VARIABLE_SYMBOLS.get(variable, variable)}}}$"


# Variable by line style, fill and size (largest drawn first, so a smaller marker on a coinciding
# point shows inside a larger one).
VARIABLE_MARKS = {"entropy": ("-", True, 4.6), "temperature": ("--", False, 6.2), "internal_energy": (":", True, 2.8)}
BACKGROUND = "0.82"


def style(key):
    """Line and marker of one scheme and variable: the family's colour, the scheme's marker, the
    variable's line style, fill and size."""
    scheme, variable = key
    colour = integrators.family_colour(scheme)
    linestyle, filled, size = VARIABLE_MARKS.get(variable, ("-.", True, 4.0))
    return dict(color=colour, marker=integrators.marker(scheme), markersize=size, linestyle=linestyle,
                markerfacecolor=colour if filled else "white", zorder=3 + 0.1 * (7 - size))


def families(keys):
    """The families of the (scheme, variable) pairs in registry order, each with its pairs."""
    grouped = {}
    for key in keys:
        grouped.setdefault(integrators.family(key[0]), []).append(key)
    return list(grouped.items())


# A family's row of panels: at least this high [in], and high enough for its legend beside it.
FAMILY_ROW_HEIGHT = 1.45
LEGEND_ENTRY_HEIGHT = 0.155


def family_rows(grouped, columns, extra_entries=0, sharex=True, sharey="col"):
    """A figure of one row of panels per family, a page wide, the panels sharing their axes; each
    row as high as its legend (one entry per scheme and variable, plus `extra_entries`) needs."""
    heights = [max(FAMILY_ROW_HEIGHT, LEGEND_ENTRY_HEIGHT * (len(keys) + extra_entries) + 0.3)
               for _, keys in grouped] or [FAMILY_ROW_HEIGHT]
    return plt.subplots(len(heights), columns, figsize=(DOUBLE_COLUMN, 0.8 + sum(heights)), sharex=sharex,
                        sharey=sharey, squeeze=False, height_ratios=heights)


def members(rows, key):
    """Indices of the rows of one scheme, by ascending dt, then tolerance (adaptive schemes)."""
    chosen = [i for i, row in enumerate(rows) if (row["scheme"], row["thermo_variable"]) == key]
    return sorted(chosen, key=lambda i: (rows[i]["dt"], rows[i].get("tolerance", 0.0)))


def error_axes(ax, conv, x_values, with_fit):
    """One curve per scheme of the convergence errors against x; the cross-check level."""
    rows, errors = conv["rows"], conv["errors"]
    for key in curve_keys(rows):
        chosen = members(rows, key)
        text = label(*key)
        if with_fit:
            fit = conv["fits"][key]
            text += f": order {fit['order']:.2f}"
        ax.plot(x_values[chosen], errors[chosen], label=text, **style(key))
    ax.axhline(conv["level"], color="black", linewidth=0.8, linestyle="-.",
               label="|reference $-$ cross-check|")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_ylabel(r"error at $t = T$: max(|$\Delta q$|, |$\Delta p$|, |$\Delta\gamma$|, "
                  r"|$\Delta\theta_a$|/$\theta_{ref}$)")
    ax.grid(True, which="major")


def reference_lines(conv):
    """Caption lines naming the reference, the cross-check and the cases of the convergence study."""
    reference, cross_check = conv["reference"], conv["cross_check"]
    return [f"Reference: {reference.path} at T = {reference.time:g} s; cross-check: {cross_check.path}; "
            f"|reference - cross-check| = {conv['level']:.1e} (dash-dot line). Errors near that level "
            "measure the reference, not the scheme. Where curves coincide (a scheme in its three "
            "variables; MP and TS-midpoint), the nested markers show it.",
            f"Cases: {len(conv['rows'])} complete of {conv['rows'][0]['index'] if conv['rows'] else '-'}"
            + (f"; left out (not complete): {len(conv['left_out'])}" if conv["left_out"] else "")]


def convergence_figure(conv, wp, fit_rule):
    """Error at t = T against dt, log-log, with the fitted order of each fixed-step scheme; beside
    it, the adaptive schemes' error at t = 5 s against their tolerance."""
    points, factor = fit_rule
    fig, (ax, adaptive) = plt.subplots(1, 2, figsize=(DOUBLE_COLUMN, 4.6), width_ratios=(3, 2))
    dt = np.array([row["dt"] for row in conv["rows"]])
    error_axes(ax, conv, dt, with_fit=True)
    fitted = np.isin([row["case"] for row in conv["rows"]],
                     np.concatenate([fit["cases"] for fit in conv["fits"].values()]))
    ax.plot(dt[fitted], conv["errors"][fitted], linestyle="none", marker="o", markersize=11,
            color="0.85", zorder=0, label="points of the order fit")
    ax.set_xlabel(r"time step $\Delta t$ [s]")
    ax.set_title(f"fixed step, t = {conv['reference'].time:g} s", loc="left")
    rows = [i for i, row in enumerate(wp["rows"]) if "tolerance" in row]
    for key in curve_keys([wp["rows"][i] for i in rows]):
        chosen = [i for i in members(wp["rows"], key) if i in rows and wp["shown"][i]]
        adaptive.plot([wp["rows"][i]["tolerance"] for i in chosen], wp["errors"][chosen], label=label(*key),
                      **style(key))
    adaptive.axhline(wp["level"], color="black", linewidth=0.8, linestyle="-.")
    adaptive.set_xscale("log")
    adaptive.set_yscale("log")
    adaptive.set_xlabel("tolerance (absolute and relative, per step)")
    adaptive.set_title(f"adaptive, t = {wp['reference'].time:g} s", loc="left")
    adaptive.grid(True, which="major")
    adaptive.legend(loc="upper left")
    fig.legend(*ax.get_legend_handles_labels(), loc="outside lower center", ncols=4)
    return fig, "Convergence: error against the time step, and of the adaptive schemes against the tolerance", \
        reference_lines(conv) + [
            f"Order: least-squares slope of log(error) on log(dt) over the asymptotic range, the {points} "
            f"smallest dt with error > {factor:g} x the cross-check level (grey discs).",
            f"Right: the adaptive cases of the work-precision study against its reference ({wp['reference'].path}); "
            f"points below {wp['level']:.1e} x 10 (the dash-dot line is the cross-check level) are left out."]


def work_precision_figure(wps, factor):
    """Error at the reference's time against the median solve time (CPU or wall: each result's
    time_kind), log-log: a column of panels per model or study ({name: work_precision result}), a
    row per scheme family (the other families in grey behind), the family named by the row's
    legend; lower left is better. A result without a cross-check has level None: no level line."""
    grouped = families(sorted({key for wp in wps.values() for key in curve_keys(wp["rows"])}, key=key_rank))
    levels = [wp["level"] for wp in wps.values() if wp["level"] is not None]
    fig, axes = family_rows(grouped, len(wps), extra_entries=1 if levels else 0, sharex="col", sharey=True)
    # Down to the decade below the lowest reference level (or error), so that every level line shows.
    lowest = min(levels + [float(np.min(wp["errors"][wp["shown"]])) for wp in wps.values() if wp["shown"].any()],
                 default=1e-11)
    bottom = min(1e-11, 10.0 ** np.floor(np.log10(lowest)))
    time_kinds = sorted({wp["time_kind"] for wp in wps.values()})
    for column, wp in enumerate(wps.values()):
        rows, errors, time = wp["rows"], wp["errors"], wp["time"]
        curves = {}
        for key in curve_keys(rows):
            chosen = [i for i in members(rows, key) if wp["shown"][i]]
            chosen.sort(key=lambda i: -errors[i])
            curves[key] = chosen
        for ax, (family, keys) in zip(axes[:, column], grouped):
            for key, chosen in curves.items():
                if key not in keys:
                    ax.plot(time[chosen], errors[chosen], color=BACKGROUND, linewidth=0.6, zorder=1)
            for key in keys:
                chosen = curves.get(key)
                if chosen:
                    ax.plot(time[chosen], errors[chosen], label=label(*key)
                            + (" (tolerance)" if "tolerance" in rows[chosen[0]] else ""), **style(key))
            if wp["level"] is not None:
                ax.axhline(wp["level"], color="black", linewidth=0.8, linestyle="-.",
                           label="|reference $-$ cross-check|")
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.set_ylim(bottom, 1.0)
            ax.grid(True, which="major")
        axes[0, column].set_title(f"{wp['title']}, {wp['end']}\n{wp['norm_label']}")
        axes[-1, column].set_xlabel(f"{TIME_AXES[wp['time_kind']][0]}, one rank [s]")
    for row_axes, (family, _) in zip(axes, grouped):
        # One legend per family, beside its row: a curve carries the same marks in every column.
        entries = {}
        for ax in row_axes:
            entries.update((text, handle) for handle, text in zip(*ax.get_legend_handles_labels()))
        row_axes[-1].legend(entries.values(), entries.keys(), title=integrators.family_title(family),
                            loc="upper left", bbox_to_anchor=(1.01, 1.0))
    fig.supylabel("error at t = T, in the norm above each column")
    repeats = sorted({row.get("repeats", 1) for wp in wps.values() for row in wp["rows"]})
    words = " and ".join(TIME_AXES[kind][0] for kind in time_kinds)
    return fig, f"Work-precision: error against {words} (lower left is better)", [
        *(f"{wp['title']}: error at {wp['end']}, {wp['norm']}. Reference: {wp['reference'].path}; "
          + (f"cross-check: {wp['cross_check'].path}; |reference - cross-check| = {wp['level']:.1e} (dash-dot "
             f"line); points with error below {factor:g} times it are left out."
             if wp["level"] is not None else "no cross-check: how far the reference itself is from the exact "
             "solution is not known, and a case with error 0 (the reference itself) is left out.")
          + f" Cases: {len(wp['rows'])} complete"
          + (f"; left out (not complete): {len(wp['left_out'])}" if wp["left_out"] else "") + "."
          for wp in wps.values()),
        f"A column per {'model' if len(wps) > 1 else 'study'}, a row per scheme family (colour; the family names "
        "its row's legend), a marker per scheme, line style and fill per thermodynamic variable; the other "
        "families' curves in grey behind, on the same axes.",
        "Points along a curve: the dt of a fixed-step scheme, or the tolerance of an adaptive one. "
        f"Solve time: {'; '.join(TIME_AXES[kind][1] for kind in time_kinds)}; of one case on one rank, the median "
        f"of {'/'.join(map(str, repeats))} runs."]


def floored(values):
    return np.maximum(values, LOG_FLOOR)


def structure_figure(structure, source):
    """Energy error and entropy-law violation against solve time, complete cases: one row of two
    panels per scheme family (the other families in grey behind), its legend beside it."""
    rows = structure["rows"]
    grouped = families(curve_keys(rows))
    fig, axes = family_rows(grouped, 2)
    panels = (("energy", "energy error"), ("violation", "entropy decrease [J/K]"))
    floor = epsilon = None
    for row_axes, (family, keys) in zip(axes, grouped):
        for ax, (name, _) in zip(row_axes, panels):
            for key in curve_keys(rows):
                chosen = members(rows, key)
                if key in keys:
                    ax.plot(structure["solve_time"][chosen], floored(structure[name][chosen]), label=label(*key),
                            **style(key))
                else:
                    ax.plot(structure["solve_time"][chosen], floored(structure[name][chosen]), color=BACKGROUND,
                            linewidth=0.6, zorder=1)
            floor = ax.axhspan(LOG_FLOOR / 10, LOG_FLOOR * 2, color="0.92", zorder=0)
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.set_ylim(bottom=LOG_FLOOR / 10)
            ax.grid(True, which="major")
        epsilon = row_axes[0].axhline(np.finfo(float).eps, color="black", linewidth=0.6, linestyle=":")
        row_axes[0].set_title(integrators.family_title(family), loc="left")
        row_axes[1].legend(*row_axes[0].get_legend_handles_labels(), loc="upper left", bbox_to_anchor=(1.01, 1.0))
    for row_axes in axes:
        for ax, (_, ylabel) in zip(row_axes, panels):
            ax.set_ylabel(ylabel)
    for ax in axes[-1]:
        ax.set_xlabel(f"{TIME_AXES[structure['time_kind']][0]} of one case [s]")
    fig.legend([floor, epsilon], [rf"zeros and values < $10^{{{np.log10(LOG_FLOOR):.0f}}}$", "machine epsilon"],
               loc="outside lower center", ncols=2)
    zero = [plain_name(*key) for key in curve_keys(rows)
            if np.all(structure["violation"][members(rows, key)] == 0)]
    time_words = TIME_AXES[structure["time_kind"]][0]
    return fig, f"Structure against cost: energy error and entropy decrease against {time_words}", [
        f"Complete cases of {source} ([0, t_end], dt from the study), one point per case, curves "
        "ordered by dt; failed cases are left out. Energy error: max_n |E_n - E_0| / |E_0|; entropy decrease: "
        "max(0, -min_n (S_(n+1) - S_n)) [J/K]. From the index: energy_drift and "
        f"min_entropy_increment. Exact zeros and values below {LOG_FLOOR:.0e} are drawn at {LOG_FLOOR:.0e} "
        f"(grey band). Solve time: {TIME_AXES[structure['time_kind']][1]}.",
        "One row per scheme family (colour), a marker per scheme, line style and fill per thermodynamic "
        "variable; the other families' curves in grey behind, on the same axes.",
        "Entropy decrease zero on every finished case: " + ", ".join(zero)]


def on_rows(grid, keys):
    """A stability grid with a row for each of `keys` (in that order), not run where it has none."""
    rows = [grid["keys"].index(key) if key in grid["keys"] else -1 for key in keys]
    shaped = dict(grid, keys=list(keys))
    for name, empty in (("outcome", -1), ("flags", ""), ("failed_at", np.nan), ("halved", 0)):
        values = np.asarray(grid[name])
        shaped[name] = np.stack([values[i] if i >= 0 else np.full(values.shape[1:], empty, dtype=values.dtype)
                                 for i in rows])
    return shaped


def stability_figure(maps):
    """One panel per scene, side by side, the schemes of every scene in the same rows (a scheme a
    scene did not run is white there): rows = schemes, columns = dt, cells coloured by outcome;
    fits a page."""
    outcomes = list(OUTCOME_TEXT)
    colours = ListedColormap([NOT_RUN_COLOUR] + [OUTCOME_COLOURS[o] for o in outcomes])
    keys = sorted({key for grid in maps.values() for key in grid["keys"]}, key=key_rank)
    fig, axes = plt.subplots(1, len(maps), figsize=(DOUBLE_COLUMN, MAP_ROW_HEIGHT * len(keys) + 2.9), sharey=True,
                             squeeze=False)
    for ax, (scene, grid) in zip(axes[0], maps.items()):
        grid = on_rows(grid, keys)
        outcome = grid["outcome"]
        ax.pcolormesh(outcome + 1, cmap=colours, vmin=0, vmax=len(outcomes), edgecolors="white",
                      linewidth=1.0)
        for i, j in np.ndindex(outcome.shape):
            text = grid["flags"][i, j]
            if np.isfinite(grid["failed_at"][i, j]):
                text = f"{grid['failed_at'][i, j]:.0f}s" + (f"{text}" if text else "")
            elif grid["halved"][i, j]:
                text = (f"{text}" if text else "") + f"h{grid['halved'][i, j]}"
            if text:
                dark = outcome[i, j] >= 0 and outcomes[outcome[i, j]] == "nonphysical"
                ax.text(j + 0.5, i + 0.5, text, ha="center", va="center", color="white" if dark else "black")
        # Categorical axes: one labelled tick per cell.
        ax.set_xticks(np.arange(len(grid["dt"])) + 0.5, [f"{dt:g}" for dt in grid["dt"]], rotation=90)
        ax.set_yticks(np.arange(len(grid["keys"])) + 0.5, [label(*key) for key in grid["keys"]])
        ax.tick_params(length=0)
        ax.set_xlabel(r"time step $\Delta t$" + ("" if grid.get("nondimensional") else " [s]"))
        ax.set_title(SCENE_TITLES.get(scene, scene))
    axes[0, 0].invert_yaxis()
    handles = [Patch(facecolor=OUTCOME_COLOURS[o], edgecolor="0.5", label=OUTCOME_TEXT[o]) for o in outcomes]
    handles.append(Patch(facecolor=NOT_RUN_COLOUR, edgecolor="0.5", label="not in the study"))
    for text in ("in a cell: 9s = the case failed in the step ending at t = 9 s",
                 "V = V also rose (energy error decides the colour)",
                 "T = the solver's last rejected root had a temperature <= 0",
                 "h3 = 3 steps were rejected and replaced by two halves"):
        handles.append(Line2D([], [], linestyle="none", label=text))
    fig.legend(handles=handles, loc="outside lower center", ncols=1, handlelength=1.5)
    return fig, "Stability map: outcome of every case", [
        "Scenes: " + "; ".join(f"{SCENE_TITLES.get(scene, scene)}: {grid['scene']}" for scene, grid in maps.items()),
        "Studies: " + "; ".join(f"{SCENE_TITLES.get(scene, scene)}: {grid['source']}" for scene, grid in maps.items()),
        "Precedence: a failed case counts as failed; our solver's 'no root' (it rejected or missed every root) "
        "is a solver failure, marked T when the last rejected root had a temperature <= 0; a finished case with "
        "a temperature <= 0 in /temperature (checked for every finished case) is non-physical; then energy error "
        "> 1e-6 (marked V when V also rose), then V rising by > 1e-8 J. Failure times are rounded to whole "
        "seconds (the summary file has them exactly)."]


def save_all(output, conv, wps, structure, maps, fit_rule, work_precision_factor, load_lines=None):
    """Writes the figures to OUTPUT/study_*.png and .pdf, with their captions in .txt: work precision
    ({model: result}) and the stability map, and the pendulum's convergence and structure against
    cost unless conv and structure are None; `load_lines` adds a caption line per figure name (the
    machine's load of a timing chart)."""
    load_lines = load_lines or {}
    output = Path(output)
    figures = {"study_work_precision": lambda: work_precision_figure(wps, work_precision_factor),
               "study_stability_map": lambda: stability_figure(maps)}
    if conv is not None:
        figures["study_convergence"] = lambda: convergence_figure(conv, wps["pendulum"], fit_rule)
    if structure is not None:
        source = structure["rows"][0]["index"].parent if structure["rows"] else "-"
        figures["study_structure_cost"] = lambda: structure_figure(structure, source)
    for name, draw in figures.items():
        save_chart(output / name, draw(), load_lines.get(name))


def save_chart(path, drawn, load_line=None):
    """Writes PATH.png, .pdf and .txt of a drawn chart, (figure, title, caption lines), with the
    machine's load as the caption's last line; a busy machine's timings are marked on the chart
    itself, not only in its caption (top right: the panels' titles are at the left or in the
    middle)."""
    fig, title, lines = drawn
    if "BUSY" in (load_line or ""):
        fig.text(0.995, 0.995, "measured on a busy machine (see the caption)", ha="right", va="top",
                 color="tab:red", fontsize=MIN_FONT_POINTS)
    save(fig, path, title, lines=lines + ([load_line] if load_line else []))
