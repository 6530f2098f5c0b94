"""Figure helpers shared by the plot scripts: command line, run descriptions, axes, saving."""
import argparse
import sys
import textwrap
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # scripts write files only; no display needed
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from trajectory import RunFileError  # noqa: E402

# Colour per thermodynamic variable, so EME and midpoint runs of one variable match.
VARIABLE_COLOURS = {"entropy": "tab:blue", "temperature": "tab:red", "internal_energy": "tab:green"}
# Increments below this size [J or J/K] are drawn on the linear part of the symlog axis.
INCREMENT_LINEAR_THRESHOLD = 1e-15


def argument_parser(description):
    """Parser with the arguments every script takes: FILE.h5 ... and -o OUT."""
    parser = argparse.ArgumentParser(description=description,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("files", nargs="+", metavar="FILE.h5", help="run files written by eme_run")
    parser.add_argument("-o", "--output", required=True, metavar="OUT",
                        help="output path without suffix: writes OUT.png and OUT.pdf")
    return parser


def output_stem(output):
    """OUT without a .png/.pdf suffix; its folder is created."""
    path = Path(output)
    if path.suffix.lower() in (".png", ".pdf"):
        path = path.with_suffix("")
    path.parent.mkdir(parents=True, exist_ok=True)
    return path


def save(fig, output):
    """Writes OUT.png and OUT.pdf, closes the figure and returns the two paths."""
    stem = output_stem(output)
    paths = [stem.with_name(stem.name + suffix) for suffix in (".png", ".pdf")]
    for path in paths:
        fig.savefig(path, dpi=150)
        print(f"wrote {path}")
    plt.close(fig)
    return paths


def describe(fig, title, runs):
    """Figure title plus one line per run: scheme, thermodynamic variable, dt, input file, status."""
    lines = [title]
    for run in runs:
        text = f"{run.name}: {run.description}"
        lines.extend(textwrap.wrap(text, 150, subsequent_indent="    ", break_long_words=False,
                                   break_on_hyphens=False))
    fig.suptitle("\n".join(lines), x=0.01, ha="left", fontsize=7)


def colour(run):
    """The run's line colour, by thermodynamic variable."""
    return VARIABLE_COLOURS.get(run.attrs["thermo_variable"], "black")


def flat_aware_limits(ax, values):
    """Keeps a conserved quantity drawn as a flat line instead of magnifying round-off.

    Matplotlib would stretch a series that varies by 1e-13 J over the whole axis; the
    increment panels already show that variation, so here the range is at least 1e-3 of the
    value. Only the view changes, never the plotted numbers."""
    values = np.concatenate([np.ravel(v) for v in values])
    low, high = values.min(), values.max()
    centre, half = 0.5 * (low + high), 0.5 * (high - low)
    minimum = 1e-3 * max(abs(centre), 1e-30)
    if half < minimum:
        ax.set_ylim(centre - 1.05 * minimum, centre + 1.05 * minimum)
    ax.ticklabel_format(axis="y", useOffset=False)


def increment_axis(ax, values):
    """Symmetric-log y axis for per-step increments.

    Why symlog: an EME energy increment is round-off (1e-13 J) while a midpoint one is of
    order 1 J, and the sign matters (dS >= 0, dV <= 0). Symlog is logarithmic on both sides
    of zero, so 1e-12 and 1 are both read off decades and the sign is the side of the axis;
    exact zeros, which a log of |increment| cannot show, sit on the thin linear band
    |x| < 1e-15, below the round-off of any quantity of this model."""
    ax.set_yscale("symlog", linthresh=INCREMENT_LINEAR_THRESHOLD, linscale=0.3)
    largest = max((np.max(np.abs(v)) for v in values if len(v)), default=0.0)
    # Labels at 1e-12 and every third decade above it; the axis ends on a labelled decade.
    decade = int(np.ceil(np.log10(largest))) if largest > 0 else -12
    top_exponent = max(-12, decade + (-(decade + 12)) % 3)
    decades = 10.0 ** np.arange(-12, top_exponent + 1, 3, dtype=float)
    top = decades[-1]
    ax.set_ylim(-top, top)
    ticks = np.concatenate([-decades[::-1], [0.0], decades])
    ax.set_yticks(ticks, [f"{t:.0e}" if t else "0" for t in ticks])
    every_decade = 10.0 ** np.arange(np.log10(INCREMENT_LINEAR_THRESHOLD), np.log10(top) + 1)
    ax.set_yticks(np.concatenate([-every_decade, every_decade]), minor=True)
    ax.grid(True, axis="y", linewidth=0.3)
    ax.tick_params(axis="y", labelsize=7)


def figure_texts(fig):
    """Every text shown in a figure (titles, labels, legends), for checks."""
    return [t.get_text() for t in fig.findobj(matplotlib.text.Text) if t.get_text()]


def run_script(main):
    """Runs a script's main(); a bad run file ends it with the message and exit status 2."""
    try:
        main()
    except RunFileError as error:
        print(f"{Path(sys.argv[0]).name}: error: {error}", file=sys.stderr)
        sys.exit(2)
