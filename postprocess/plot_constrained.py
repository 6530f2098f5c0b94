"""Fig. 5 analogue: energy E, entropy S and Lyapunov function V over time, and the Lyapunov
increment V_{n+1} - V_n, for constrained EME_theta runs (g1 fixes the length of spring 1,
g2 its temperature; one run file per constraint set). The legend names each run's
constraints from the file's constraint attributes; V uses the file's theta_r.
"""
import matplotlib

from plotting import argument_parser, describe, increment_axis, plt, run_script, save
from trajectory import CONSTRAINT_ATTRIBUTES, constraint_summary, increments, read_run

PANELS = [("energy", "E [J]"), ("entropy", "S [J/K]"), ("lyapunov", r"V = E - $\theta_R$ S [J]")]


def make_figure(runs, title="Constrained runs: energy, entropy and Lyapunov function"):
    """E, S, V (three panels) and the Lyapunov increment (fourth panel), one colour per run."""
    fig, axes = plt.subplots(2, 2, figsize=(12, 8), sharex=True, layout="constrained")
    colours = matplotlib.colormaps["tab10"].colors
    for index, run in enumerate(runs):
        label = rf"{run.label}, {constraint_summary(run)}, $\theta_R$ = {run.attrs['theta_r']:g} K"
        style = dict(color=colours[index % len(colours)], linewidth=1.0, label=label)
        time = run.data["time"]
        for (name, _), ax in zip(PANELS, axes.flat):
            ax.plot(time, run.data[name], **style)
        axes[1, 1].plot(time[1:], increments(run.data["lyapunov"]), marker=".", markersize=4,
                        linestyle="none", color=style["color"])
    for (_, label), ax in zip(PANELS, axes.flat):
        ax.set_ylabel(label)
        ax.ticklabel_format(axis="y", useOffset=False)
    increment_axis(axes[1, 1], [increments(run.data["lyapunov"]) for run in runs])
    axes[1, 1].set_ylabel(r"$V_{n+1} - V_n$ [J]")
    axes[1, 0].set_xlabel(r"time $t_n$ [s]")
    axes[1, 1].set_xlabel(r"time $t_{n+1}$ [s] (increment of step n $\to$ n+1)")
    fig.legend(*axes[0, 0].get_legend_handles_labels(), loc="outside lower center", ncols=1, fontsize=8)
    describe(fig, title, runs)
    return fig


def main(argv=None):
    args = argument_parser(__doc__).parse_args(argv)
    runs = [read_run(path, [name for name, _ in PANELS], CONSTRAINT_ATTRIBUTES) for path in args.files]
    return save(make_figure(runs), args.output)


if __name__ == "__main__":
    run_script(main)
