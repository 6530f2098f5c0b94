"""Spring temperatures theta_1, theta_2 and the angular momentum drift J_z,n - J_z,0 over time,
for one or more runs (one curve per run file, each in its own colour and marker; --labels names
them). One journal column wide; with --compare runs a page wide, the files in the left column of
panels and the compared runs (dashed, open markers) in the right, on the same axes, so that six
runs whose temperatures nearly coincide (EME and the midpoint rule in three variables) are not
drawn over each other.
"""
from plotting import (DOUBLE_COLUMN, SINGLE_COLUMN, add_compare_argument, apply_labels, argument_parser, parse_arguments,
                      plot_marked, plt, run_script, run_styles, save)
from trajectory import jz_drift, read_run

TITLE = "Spring temperatures and angular momentum drift"


def set_title(runs):
    """A column's title: the schemes of its runs, in the order given."""
    return ", ".join(dict.fromkeys(run.name.rsplit("_", 1)[0] for run in runs))


def make_figure(runs, compare=()):
    """theta_1 (top), theta_2 (middle) from /temperature and J_z drift (bottom); the `compare` runs
    in a column of their own, dashed, the rows sharing their y axes."""
    sets = [list(zip(runs, styles)) for runs, styles in ((runs, run_styles(runs)),
                                                         (compare, run_styles(compare, compare=True))) if runs]
    fig, axes = plt.subplots(3, len(sets), figsize=(DOUBLE_COLUMN if len(sets) > 1 else SINGLE_COLUMN, 5.2),
                             sharex=True, sharey="row", squeeze=False)
    for column, drawn in enumerate(sets):
        for run, style in drawn:
            time = run.data["time"]
            for name, ax in zip(("theta_1", "theta_2"), axes[:2, column]):
                plot_marked(ax, time, run.column("temperature", name), style, label=run.label)
            plot_marked(axes[2, column], time, jz_drift(run), style)
        if len(sets) > 1:
            axes[0, column].set_title(set_title([run for run, _ in drawn]) + (" (--compare)" if column else ""))
        axes[2, column].set_xlabel(r"time $t_n$ [s]")
    axes[0, 0].set_ylabel(r"$\theta_1$ (spring 1) [K]")
    axes[1, 0].set_ylabel(r"$\theta_2$ (spring 2) [K]")
    axes[2, 0].set_ylabel(r"$J_{z,n} - J_{z,0}$ [J s]")
    handles = [handle for column in range(len(sets)) for handle in axes[0, column].get_legend_handles_labels()[0]]
    labels = [label for column in range(len(sets)) for label in axes[0, column].get_legend_handles_labels()[1]]
    fig.legend(handles, labels, loc="outside lower center", ncols=2)
    return fig


def main(argv=None):
    parser = argument_parser(__doc__)
    add_compare_argument(parser)
    args = parse_arguments(parser, argv)
    needed = ["temperature", "angular_momentum"]
    runs = [read_run(path, needed) for path in args.files]
    compare = [read_run(path, needed) for path in args.compare]
    apply_labels(parser, args.labels, [*runs, *compare])
    return save(make_figure(runs, compare), args.output, TITLE, [*runs, *compare])


if __name__ == "__main__":
    run_script(main)
