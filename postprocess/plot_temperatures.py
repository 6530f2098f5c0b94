"""Spring temperatures theta_1, theta_2 and the angular momentum drift J_z,n - J_z,0 over time,
for one or more runs (one curve per run file, each in its own colour and marker; --compare
runs are dashed with open markers; --labels names them). One journal column wide.
"""
from plotting import (SINGLE_COLUMN, add_compare_argument, apply_labels, argument_parser, parse_arguments,
                      plot_marked, plt, run_script, save, styled_runs)
from trajectory import jz_drift, read_run

TITLE = "Spring temperatures and angular momentum drift"


def make_figure(runs, compare=()):
    """theta_1 (top), theta_2 (middle) from /temperature and J_z drift (bottom)."""
    fig, axes = plt.subplots(3, 1, figsize=(SINGLE_COLUMN, 5.2), sharex=True)
    drawn = styled_runs(runs, compare)
    for run, style in drawn:
        time = run.data["time"]
        for name, ax in zip(("theta_1", "theta_2"), axes[:2]):
            plot_marked(ax, time, run.column("temperature", name), style, label=run.label)
        plot_marked(axes[2], time, jz_drift(run), style)
    axes[0].set_ylabel(r"$\theta_1$ (spring 1) [K]")
    axes[1].set_ylabel(r"$\theta_2$ (spring 2) [K]")
    axes[2].set_ylabel(r"$J_{z,n} - J_{z,0}$ [J s]")
    axes[2].set_xlabel(r"time $t_n$ [s]")
    fig.legend(*axes[0].get_legend_handles_labels(), loc="outside lower center", ncols=2)
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
