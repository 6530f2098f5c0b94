"""Spring temperatures theta_1, theta_2 and the conserved angular momentum's drift J_z,n - J_z,0
(a planar scene's scalar J_n - J_0) over time,
for one or more runs (one curve per run file, each in its own colour and marker; --labels names
them). One journal column wide; with --compare runs a page wide, the files in the left column of
panels and the compared runs (dashed, open markers) in the right, on the same axes, so that six
runs whose temperatures nearly coincide (EME and the midpoint rule in three variables) are not
drawn over each other.
"""
from plotting import (DOUBLE_COLUMN, SINGLE_COLUMN, add_compare_argument, apply_labels, argument_parser, parse_arguments,
                      plot_marked, plt, run_script, run_styles, save)
from trajectory import RunFileError, momentum_drift, read_run

TITLE = "Spring temperatures and angular momentum drift"
# A spring chain's file is refused (its springs are more than two): what draws it.
CHAIN_INSTEAD = ("plot_chain_temperatures.py {file} -o OUT (every spring's temperature over time) and "
                 "summarize_runs.py {file} (its balances, and the momentum drift where the scene conserves one)")


def set_title(runs):
    """A column's title: the schemes of its runs, in the order given."""
    return ", ".join(dict.fromkeys(run.name.rsplit("_", 1)[0] for run in runs))


MOMENTUM_LABELS = {"J": r"$J_n - J_0$ [J s]"}


def momentum_label(name):
    """The drift's axis label: J_n - J_0 of the planar J, J_{y,n} - J_{y,0} of J_y (J_x, J_z, J_g)."""
    axis = name.split("_")[-1]
    return MOMENTUM_LABELS.get(name, rf"$J_{{{axis},n}} - J_{{{axis},0}}$ [J s]")


def make_figure(runs, compare=()):
    """theta_1 (top), theta_2 (middle) from /temperature and the conserved momentum's drift
    (bottom: J_z, or the planar scalar J; of several components, the one that drifts furthest);
    the `compare` runs in a column of their own, dashed, the rows sharing their y axes. A run without temperatures (elastic springs) or without a
    conserved momentum (a planar scene under gravity) is left out of those rows, and a row no run
    has is not drawn."""
    sets = [list(zip(runs, styles)) for runs, styles in ((runs, run_styles(runs)),
                                                         (compare, run_styles(compare, compare=True))) if runs]
    everything = [*runs, *compare]
    thermal = any(run.has("temperature") for run in everything)
    momenta = {name for name in (momentum_drift(run)[0] for run in everything) if name}
    if not thermal and not momenta:
        raise RunFileError(f"{everything[0].path}: neither temperatures nor a conserved momentum to draw "
                           "(elastic springs in a planar scene under gravity?)")
    names = (["theta_1", "theta_2"] if thermal else []) + (["momentum"] if momenta else [])
    fig, axes = plt.subplots(len(names), len(sets), figsize=(DOUBLE_COLUMN if len(sets) > 1 else SINGLE_COLUMN,
                                                            1.2 + 1.33 * len(names)),
                             sharex=True, sharey="row", squeeze=False)
    for column, drawn in enumerate(sets):
        for run, style in drawn:
            time = run.data["time"]
            labelled = False
            for name, ax in zip(names, axes[:, column]):
                if name == "momentum":
                    drift = momentum_drift(run)[1]
                    if drift is not None:
                        plot_marked(ax, time, drift, style, label=None if labelled else run.label)
                elif run.has("temperature"):
                    plot_marked(ax, time, run.column("temperature", name), style, label=run.label)
                    labelled = True
        if len(sets) > 1:
            axes[0, column].set_title(set_title([run for run, _ in drawn]) + (" (--compare)" if column else ""))
        axes[-1, column].set_xlabel(r"time $t_n$ [s]")
    labels = {"theta_1": r"$\theta_1$ (spring 1) [K]", "theta_2": r"$\theta_2$ (spring 2) [K]",
              "momentum": momentum_label(momenta.pop()) if len(momenta) == 1 else
              r"conserved momentum drift ($J_z$ or $J$) [J s]"}
    for row, name in enumerate(names):
        axes[row, 0].set_ylabel(labels[name])
    # Every run once, from whichever row it is drawn in (a run without temperatures: the momentum row).
    legend = {}
    for ax in axes.T.flat:
        for handle, label in zip(*ax.get_legend_handles_labels()):
            legend.setdefault(label, handle)
    fig.legend(list(legend.values()), list(legend.keys()), loc="outside lower center", ncols=2)
    return fig


def main(argv=None):
    parser = argument_parser(__doc__)
    add_compare_argument(parser)
    args = parse_arguments(parser, argv)
    # The temperatures of every run with thermal unknowns; the momenta where the scene has them.
    runs = [read_run(path, [], optional=["angular_momentum"], thermal_datasets=["temperature"],
                     chain_instead=CHAIN_INSTEAD) for path in args.files]
    compare = [read_run(path, [], optional=["angular_momentum"], thermal_datasets=["temperature"],
                        chain_instead=CHAIN_INSTEAD) for path in args.compare]
    apply_labels(parser, args.labels, [*runs, *compare])
    return save(make_figure(runs, compare), args.output, TITLE, [*runs, *compare])


if __name__ == "__main__":
    run_script(main)
