"""Fig. 4 analogue: energy E, entropy S and Lyapunov function V over time, and their per-step
increments X_{n+1} - X_n, for EME_s, EME_theta and EME_u (one run file each).

Increments are drawn on a symmetric-log axis, so a round-off increment of 1e-12 and a
midpoint-rule increment of 1 J are both readable and the sign is the side of zero.

Example: plot_balance.py eme_s.h5 eme_theta.h5 eme_u.h5 --compare mp_s.h5 mp_theta.h5 mp_u.h5 -o fig4
"""
from plotting import (argument_parser, colour, describe, flat_aware_limits, increment_axis,
                      plt, run_script, save)
from trajectory import increments, read_run

QUANTITIES = [("energy", "E [J]", r"$E_{n+1}-E_n$ [J]"),
              ("entropy", "S [J/K]", r"$S_{n+1}-S_n$ [J/K]"),
              ("lyapunov", r"V = E - $\theta_R$ S [J]", r"$V_{n+1}-V_n$ [J]")]


def make_figure(runs, compare=(), title="Energy, entropy and Lyapunov function"):
    """Values (left) and increments (right) of E, S, V; `compare` runs are drawn dashed."""
    fig, axes = plt.subplots(len(QUANTITIES), 2, figsize=(12, 9), sharex=True, layout="constrained")
    for row, (name, value_label, increment_label) in enumerate(QUANTITIES):
        values_ax, increments_ax = axes[row]
        for run, style in [(r, "main") for r in runs] + [(r, "compare") for r in compare]:
            dashed = style == "compare"
            line = dict(color=colour(run), label=run.label, linewidth=1.0,
                        linestyle="--" if dashed else "-")
            # Markers only: a line joining increments of opposite sign would cross every decade.
            marker = dict(color=colour(run), marker="x" if dashed else ".", markersize=4,
                          linestyle="none")
            time, values = run.data["time"], run.data[name]
            values_ax.plot(time, values, **line)
            increments_ax.plot(time[1:], increments(values), **marker)
        everything = [*runs, *compare]
        flat_aware_limits(values_ax, [r.data[name] for r in everything])
        increment_axis(increments_ax, [increments(r.data[name]) for r in everything])
        values_ax.set_ylabel(value_label)
        increments_ax.set_ylabel(increment_label)
    axes[-1, 0].set_xlabel(r"time $t_n$ [s]")
    axes[-1, 1].set_xlabel(r"time $t_{n+1}$ [s] (increment of step n $\to$ n+1)")
    fig.legend(*axes[0, 0].get_legend_handles_labels(), loc="outside lower center",
               ncols=3, fontsize=8)
    describe(fig, title, [*runs, *compare])
    return fig


def main(argv=None):
    parser = argument_parser(__doc__)
    parser.add_argument("--compare", nargs="+", default=[], metavar="FILE.h5",
                        help="midpoint-rule (or any other) runs to overlay, drawn dashed")
    args = parser.parse_args(argv)
    needed = [name for name, _, _ in QUANTITIES]
    runs = [read_run(path, needed) for path in args.files]
    compare = [read_run(path, needed) for path in args.compare]
    return save(make_figure(runs, compare), args.output)


if __name__ == "__main__":
    run_script(main)
