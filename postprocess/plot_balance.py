"""Fig. 4 analogue: energy E, entropy S and Lyapunov function V over time, and their per-step
increments X_{n+1} - X_n, for EME_s, EME_theta and EME_u (one run file each).

Increments are drawn on a symmetric-log axis, so a round-off increment of 1e-12 and a
midpoint-rule increment of 1 J are both readable and the sign is the side of zero. Every run has its own colour and
marker (by thermodynamic variable, or by scheme and variable; plotting.run_styles); --compare runs
are dashed with open markers; --labels names the runs. A long run shows the extremes of each
stretch of steps rather than a marker per step (plotting.thinned). A file written with &output
every or interval holds every N-th point: its increments are over the steps between written
points, as the axis label and the caption say (its per-step extremes of S and V are the
datasets /min_entropy_increment and /max_lyapunov_increment, which summarize_runs.py reports).

Example: plot_balance.py eme_s.h5 eme_theta.h5 eme_u.h5 --compare mp_s.h5 mp_theta.h5 mp_u.h5 -o fig4
"""
from plotting import (DOUBLE_COLUMN, add_compare_argument, apply_labels, argument_parser, flat_aware_limits,
                      increment_axis, parse_arguments, plot_marked, plot_points, plt, run_script, save, styled_runs)
from trajectory import increments, read_run

TITLE = "Energy, entropy and Lyapunov function and their per-step increments"
QUANTITIES = [("energy", "$E$ [J]", r"$E_{n+1}-E_n$ [J]"),
              ("entropy", "$S$ [J/K]", r"$S_{n+1}-S_n$ [J/K]"),
              ("lyapunov", r"$V = E - \theta_R S$ [J]", r"$V_{n+1}-V_n$ [J]")]


def make_figure(runs, compare=()):
    """Values (left) and increments (right) of E, S, V; `compare` runs are drawn dashed. S and V
    are drawn for the runs that have them (elastic springs have no entropy): a row only where
    some run has its quantity."""
    drawn = styled_runs(runs, compare)
    quantities = [quantity for quantity in QUANTITIES if any(run.has(quantity[0]) for run, _ in drawn)]
    fig, axes = plt.subplots(len(quantities), 2, figsize=(DOUBLE_COLUMN, 6.2 * len(quantities) / len(QUANTITIES)
                                                          + (0.6 if len(quantities) < len(QUANTITIES) else 0)),
                             sharex=True, squeeze=False)
    for row, (name, value_label, increment_label) in enumerate(quantities):
        values_ax, increments_ax = axes[row]
        for run, style in drawn:
            if not run.has(name):
                continue
            time, values = run.data["time"], run.data[name]
            plot_marked(values_ax, time, values, style, label=run.label)
            plot_points(increments_ax, time[1:], increments(values), style)
        everything = [run for run, _ in drawn if run.has(name)]
        flat_aware_limits(values_ax, [r.data[name] for r in everything])
        increment_axis(increments_ax, [increments(r.data[name]) for r in everything])
        values_ax.set_ylabel(value_label)
        increments_ax.set_ylabel(increment_label)
    axes[-1, 0].set_xlabel(r"time $t_n$ [s]")
    if any(run.strided for run, _ in drawn):
        axes[-1, 1].set_xlabel(r"time $t_{n+1}$ [s] (increment between written points $n \to n+1$)")
    else:
        axes[-1, 1].set_xlabel(r"time $t_{n+1}$ [s] (increment of step $n \to n+1$)")
    fig.legend(*axes[0, 0].get_legend_handles_labels(), loc="outside lower center", ncols=3)
    return fig


def main(argv=None):
    parser = argument_parser(__doc__)
    add_compare_argument(parser)
    args = parse_arguments(parser, argv)
    # E of every run; S and V of every run with thermal unknowns (not of elastic springs).
    thermal = [name for name, _, _ in QUANTITIES[1:]]
    runs = [read_run(path, ["energy"], thermal_datasets=thermal) for path in args.files]
    compare = [read_run(path, ["energy"], thermal_datasets=thermal) for path in args.compare]
    apply_labels(parser, args.labels, [*runs, *compare])
    strided = [f"{run.path}: {run.rows_written} rows for {run.steps} steps (&output every or interval): its "
               "increments are between written points, not per step" for run in [*runs, *compare] if run.strided]
    return save(make_figure(runs, compare), args.output, TITLE, [*runs, *compare], lines=strided)


if __name__ == "__main__":
    run_script(main)
