"""Fig. 5 analogue: energy E, entropy S and Lyapunov function V over time, and the Lyapunov
increment V_{n+1} - V_n, for constrained EME_theta runs (g1 fixes the length of spring 1,
g2 its temperature; one run file per constraint set). The legend names each run's
constraints from the file's constraint attributes; V uses the file's theta_R.

When the runs have different reference temperatures theta_R, their V are different functions:
the V panels say so, and each theta_R has its own line style.
"""
import matplotlib

from plotting import (DOUBLE_COLUMN, argument_parser, curve_style, increment_axis, parse_arguments,
                      plot_marked, plot_points, plt, run_script, save)
from trajectory import CONSTRAINT_ATTRIBUTES, constraint_summary, increments, read_run

TITLE = "Constrained runs: energy, entropy and Lyapunov function"
PANELS = [("energy", "$E$ [J]"), ("entropy", "$S$ [J/K]"), ("lyapunov", r"$V = E - \theta_R S$ [J]")]
LINESTYLES = (("-", "solid"), ("--", "dashed"), (":", "dotted"), ("-.", "dash-dot"))


def reference_temperature(run):
    """theta_R as text, e.g. '300 K' (a killed run's file may lack it)."""
    return f"{run.attrs['theta_r']:g} K" if "theta_r" in run.attrs else "missing"


def make_figure(runs):
    """E, S, V (three panels) and the Lyapunov increment (fourth panel), one colour per run and
    one line style per theta_R."""
    fig, axes = plt.subplots(2, 2, figsize=(DOUBLE_COLUMN, 4.6), sharex=True)
    colours = matplotlib.colormaps["tab10"].colors
    references = list(dict.fromkeys(reference_temperature(run) for run in runs))
    for index, run in enumerate(runs):
        theta_r = reference_temperature(run)
        label = rf"{run.label}, {constraint_summary(run)}, $\theta_R$ = {theta_r}"
        style = curve_style(colours[index % len(colours)], index,
                            linestyle=LINESTYLES[references.index(theta_r) % len(LINESTYLES)][0])
        time = run.data["time"]
        for (name, _), ax in zip(PANELS, axes.flat):
            if run.has(name):         # elastic springs have no S and no V
                plot_marked(ax, time, run.data[name], style, label=label)
        if run.has("lyapunov"):
            plot_points(axes[1, 1], time[1:], increments(run.data["lyapunov"]), style)
    for (_, label), ax in zip(PANELS, axes.flat):
        ax.set_ylabel(label)
        ax.ticklabel_format(axis="y", useOffset=False)
    increment_axis(axes[1, 1], [increments(run.data["lyapunov"]) for run in runs if run.has("lyapunov")])
    axes[1, 1].set_ylabel(r"$V_{n+1} - V_n$ [J]")
    if len(references) > 1:
        note = (r"$V$ of each run with its own $\theta_R$: "
                + ", ".join(f"{LINESTYLES[i % len(LINESTYLES)][1]} {theta_r}" for i, theta_r in enumerate(references)))
        axes[1, 0].set_title(note, loc="left")
        axes[1, 1].set_title(r"increments of each run's own $V$", loc="left")
    axes[1, 0].set_xlabel(r"time $t_n$ [s]")
    axes[1, 1].set_xlabel(r"time $t_{n+1}$ [s] (increment of step $n \to n+1$)")
    fig.legend(*axes[0, 0].get_legend_handles_labels(), loc="outside lower center", ncols=1)
    return fig


def main(argv=None):
    args = parse_arguments(argument_parser(__doc__), argv)
    runs = [read_run(path, ["energy"], CONSTRAINT_ATTRIBUTES, thermal_datasets=["entropy", "lyapunov"],
                     chain_instead="plot_balance.py {file} -o OUT (E, S and V; a chain has no constraints)")
            for path in args.files]
    return save(make_figure(runs), args.output, TITLE, runs)


if __name__ == "__main__":
    run_script(main)
