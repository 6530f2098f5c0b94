"""Spring temperatures theta_1, theta_2 and the angular momentum drift J_z,n - J_z,0 over time,
for one or more runs (one curve per run file).
"""
from plotting import argument_parser, colour, describe, plt, run_script, save
from trajectory import jz_drift, read_run

LINESTYLES = {"eme": "-", "midpoint": "--"}


def make_figure(runs, title="Spring temperatures and angular momentum drift"):
    """theta_1 (top), theta_2 (middle) from /temperature and J_z drift (bottom)."""
    fig, axes = plt.subplots(3, 1, figsize=(9, 8), sharex=True, layout="constrained")
    for run in runs:
        style = dict(color=colour(run), linestyle=LINESTYLES.get(run.attrs["scheme"], ":"),
                     linewidth=1.0, label=run.label)
        time = run.data["time"]
        for name, ax in zip(("theta_1", "theta_2"), axes[:2]):
            ax.plot(time, run.column("temperature", name), **style)
        axes[2].plot(time, jz_drift(run), marker=".", markersize=3, **style)
    axes[0].set_ylabel(r"$\theta_1$ (spring 1) [K]")
    axes[1].set_ylabel(r"$\theta_2$ (spring 2) [K]")
    axes[2].set_ylabel(r"$J_{z,n} - J_{z,0}$ [J s]")
    axes[2].set_xlabel(r"time $t_n$ [s]")
    fig.legend(*axes[0].get_legend_handles_labels(), loc="outside lower center", ncols=3, fontsize=8)
    describe(fig, title, runs)
    return fig


def main(argv=None):
    args = argument_parser(__doc__).parse_args(argv)
    runs = [read_run(path, ["temperature", "angular_momentum"]) for path in args.files]
    return save(make_figure(runs), args.output)


if __name__ == "__main__":
    run_script(main)
