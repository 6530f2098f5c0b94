"""The temperatures along a spring chain over time, at a glance: spring index by time, a colour map
(issue 39, item 7; docs/figures.md).

  plot_chain_temperatures.py FILE.h5 -o OUT

FILE.h5 is a spring chain's run file of either path (docs/output.md, A chain's file), read by
chain_dataset.open_chain: a file split over ranks gives its snapshots (/snapshots/theta by
/snapshots/time), a dense run's file every point (/temperature by /time); chain_bench
-chain_snapshots files are snapshots too. Also writes OUT.csv: the drawn temperatures, one row per
time, one column per spring.
"""
import csv
import sys
from pathlib import Path

import numpy as np

from chain_dataset import open_chain
from plotting import SINGLE_COLUMN, argument_parser, parse_arguments, plt, save
from trajectory import RunFileError


def chain_temperatures(path):
    """(time [s], temperatures [K] as time by spring, the datasets' names, the file's status) of a
    chain's file."""
    with open_chain(path) as chain:
        if "theta" not in chain:
            raise RunFileError(f"{path}: a chain without temperatures (spring_law "
                               f"'{chain.attrs.get('spring_law', '?')}'): neither /snapshots/theta nor /temperature")
        try:
            time, theta = chain["snapshot_time"].values, chain["theta"].values
        except OSError as error:
            raise RunFileError(f"{path}: cannot read the temperatures ({error}); the file may be damaged") from None
        source, status = chain.attrs["snapshot_source"], str(chain.attrs.get("status", ""))
    names = ("snapshots/time", "snapshots/theta") if source == "/snapshots" else ("time", "temperature")
    if time.shape[0] < 1 or theta.shape[1] < 1:
        raise RunFileError(f"{path}: /{names[1]} is empty")
    return np.asarray(time, float), np.asarray(theta, float), names, status


def figure(path, output):
    time, theta, names, status = chain_temperatures(path)
    fig, ax = plt.subplots(figsize=(SINGLE_COLUMN * 1.3, 2.6), layout="constrained")
    springs = np.arange(1, theta.shape[1] + 1)
    # Cell edges: each row of the file stands at its time, each column for its spring.
    time_edges = (np.concatenate([[time[0]], 0.5 * (time[1:] + time[:-1]), [time[-1]]])
                  if time.size > 1 else np.array([time[0] - 0.5, time[0] + 0.5]))
    spring_edges = np.arange(0.5, theta.shape[1] + 1.0)
    mesh = ax.pcolormesh(time_edges, spring_edges, theta.T, cmap="inferno", shading="flat")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("spring (1: at the support)")
    fig.colorbar(mesh, ax=ax, label="temperature [K]")
    title = f"temperatures along the chain over time: {Path(path).name} (/{names[1]}, {springs.size} springs)"
    ax.set_title(f"{springs.size} springs, /{names[1]}", fontsize=8)
    # A file a stopped run left (chain_bench's have no status) is drawn as far as it goes, and says so.
    incomplete = ([f"{path}: INCOMPLETE, drawn as far as it goes (status: {status})"]
                  if status not in ("", "complete") else [])
    for line in incomplete:
        print(f"plot_chain_temperatures.py: {line}", file=sys.stderr)
    paths = save(fig, output, title, lines=incomplete)
    table = Path(paths[0]).with_suffix(".csv")
    with open(table, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["time_s", *(f"theta_{a}_K" for a in springs)])
        for t, row in zip(time, theta):
            writer.writerow([f"{t:.9g}", *(f"{value:.9g}" for value in row)])
    print(f"wrote {table}")
    return paths


def main(argv=None):
    parser = argument_parser(__doc__.split("\n\n")[0])
    args = parse_arguments(parser, argv)
    if len(args.files) != 1:
        parser.error("one chain file at a time")
    try:
        figure(args.files[0], args.output)
    except RunFileError as error:
        print(f"plot_chain_temperatures.py: error: {error}", file=sys.stderr)
        sys.exit(2)


if __name__ == "__main__":
    main()
