#!/usr/bin/env python3
"""The machine's load at the time of a measurement, for every timing chart and bench table.

A timing taken while other work shares the cores says little: each chart and bench table that
shows times records the 1-minute load average just before and just after its measurement and
the number of cores the process may run on, and warns when the machine was busy. The load
average counts the measurement's own processes too (a study on 2 ranks adds up to 2 by its
end), so the load of the others is estimated as the larger of the load before and the load
after less the measurement's own processes; the machine counts as busy when that exceeds half
the cores.

A study index records the same load itself (eme_ensemble: `from_index`). As a program it wraps
a command (make study wraps each mpirun of eme_ensemble):

  machine_load.py --record FILE.json [--own N] -- COMMAND [ARGUMENT ...]

runs COMMAND, writes the load before and after it to FILE.json, prints the load line after the
command's output (and the warning to stderr when the machine was busy), and exits with COMMAND's
exit status.
"""
import argparse
import json
import os
import subprocess
import sys
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path


def cores():
    """The cores this process may run on (its CPU affinity), else the machine's."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def load_average():
    """The 1-minute load average (NaN where the system has none)."""
    try:
        return os.getloadavg()[0]
    except (AttributeError, OSError):
        return float("nan")


@dataclass
class MachineLoad:
    """The load around one measurement: 1-minute load averages before and after it, the cores,
    and the processes the measurement ran itself (counted in the load after it)."""
    before: float
    after: float
    cores: int
    own: int = 1

    @property
    def others(self):
        """The estimated load of everything but the measurement."""
        return max(self.before, self.after - self.own)

    @property
    def busy(self):
        """True when the others' load exceeded half the cores."""
        return self.others > 0.5 * self.cores

    def text(self):
        """One line for a caption or a table: the loads, the cores and whether it was busy."""
        line = (f"machine load: 1-minute load average {self.before:.2f} before and {self.after:.2f} after the "
                f"measurement ({self.own} process{'es' if self.own != 1 else ''} of its own), {self.cores} cores")
        return line + (f"; BUSY: the others' load {self.others:.2f} exceeded half the cores, timings are not "
                       "comparable with an idle machine's" if self.busy else "; idle enough (others' load "
                       f"{self.others:.2f} <= half the cores)")

    def warning(self):
        """The warning line for stderr, or '' when the machine was not busy."""
        return (f"warning: the machine was busy during the measurement (load average {self.before:.2f} before, "
                f"{self.after:.2f} after, {self.own} own process{'es' if self.own != 1 else ''}, {self.cores} "
                "cores): its timings are not comparable with an idle machine's") if self.busy else ""

    def fields(self):
        """The machine-readable fields that end a bench part: load_average_before=... busy=0."""
        return (f"load_average_before={self.before:.2f} load_average_after={self.after:.2f} cores={self.cores} "
                f"busy={int(self.busy)}")

    def report(self, program):
        """Prints the load line and the fields line that end a bench part, and `program`'s warning
        to stderr when the machine was busy."""
        print(self.text())
        print(self.fields())
        if self.busy:
            print(f"{program}: {self.warning()}", file=sys.stderr)

    def attributes(self):
        """The figures as HDF5 attributes or JSON fields."""
        return {"load_average_before": self.before, "load_average_after": self.after, "cores": self.cores,
                "own_processes": self.own, "busy": int(self.busy)}


@contextmanager
def measured(own=1):
    """Records the load around the block: `with measured(own=2) as load: ...`; load.after is set
    when the block ends."""
    load = MachineLoad(before=load_average(), after=float("nan"), cores=cores(), own=own)
    try:
        yield load
    finally:
        load.after = load_average()


def combined(loads):
    """One record for several measurements: the highest loads before and after, the most own processes."""
    loads = list(loads)
    return MachineLoad(before=max(load.before for load in loads), after=max(load.after for load in loads),
                       cores=min(load.cores for load in loads), own=max(load.own for load in loads))


def read(path):
    """The MachineLoad a --record FILE.json holds, or None when there is no such file."""
    path = Path(path)
    if not path.exists():
        return None
    fields = json.loads(path.read_text())
    return MachineLoad(before=fields["load_average_before"], after=fields["load_average_after"],
                       cores=fields["cores"], own=fields["own_processes"])


def from_index(path):
    """The MachineLoad a study index records (its 1-minute load averages at the study's start and
    end, its cores and ranks: eme_ensemble writes them), or None when it records none or the study
    has not ended (docs/studies.md, Index)."""
    import h5py        # (only here: the program itself needs no h5py)

    with h5py.File(path, "r") as index:
        attrs = index.attrs
        if not {"load_average_start", "load_average_end", "cores_start", "ranks"} <= set(attrs):
            return None
        return MachineLoad(before=float(attrs["load_average_start"][0]), after=float(attrs["load_average_end"][0]),
                           cores=int(attrs["cores_start"]), own=int(attrs["ranks"]))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     usage="machine_load.py --record FILE.json [--own N] -- COMMAND [ARGUMENT ...]")
    parser.add_argument("--record", required=True, metavar="FILE.json", help="where the loads go")
    parser.add_argument("--own", type=int, default=1, metavar="N",
                        help="processes the command runs itself (mpirun -n N: N; default 1)")
    parser.add_argument("command", nargs=argparse.REMAINDER, help="the command, after --")
    args = parser.parse_args(argv)
    command = args.command[1:] if args.command[:1] == ["--"] else args.command
    if not command:
        parser.error("no command to run after --")
    with measured(own=args.own) as load:
        status = subprocess.run(command).returncode
    record = Path(args.record)
    record.parent.mkdir(parents=True, exist_ok=True)
    record.write_text(json.dumps({**load.attributes(), "command": command}, indent=1) + "\n")
    print(load.text())
    if load.busy:
        print(f"machine_load.py: {load.warning()}", file=sys.stderr)
    return status


if __name__ == "__main__":
    sys.exit(main())
