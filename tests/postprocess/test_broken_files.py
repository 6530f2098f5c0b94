"""Every postprocess script on the files a killed, stopped or damaged run leaves (issue 13): a
usable file is drawn or summarised as far as it goes and marked INCOMPLETE with what is
missing; an unusable one is named with the reason and exit status 2. Never a traceback.

The broken files are made with h5py from a synthetic run of the documented layout: missing
attributes (a run killed before its end never writes its times and final status), point
datasets cut short, step datasets longer than the points allow (a kill between the two
flushes), a file without any state, the first 96 bytes of a run file (what a kill before the
first flush left), a file cut in half, and a text file."""
import functools
import importlib
import re
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
POSTPROCESS = ROOT / "postprocess"
sys.path.insert(0, str(POSTPROCESS))

import plotting  # noqa: E402
from synthetic_runs import constraint_attributes, write_run  # noqa: E402

STEPS = 6
KILLED_STATUS = "incomplete: running"


def good_run(path):
    """A complete synthetic run that every script accepts (constraint attributes included)."""
    return write_run(path, steps=STEPS, attributes={"dt": 0.15, **constraint_attributes(True, False)})[0]


def cut_datasets(path, rows_of):
    """Rewrites the datasets of a file with fewer (or more) rows, keeping their attributes."""
    with h5py.File(path, "r+") as f:
        for name, rows in rows_of(f).items():
            data, attrs = f[name][()], dict(f[name].attrs)
            if rows > len(data):
                data = np.concatenate([data, np.repeat(data[-1:], rows - len(data), axis=0)])
            del f[name]
            f[name] = data[:rows]
            f[name].attrs.update(attrs)


def point_names(f):
    return [name for name in f if f[name].attrs["rows"] == "point"]


def step_names(f):
    return [name for name in f if f[name].attrs["rows"] == "step"]


def killed(path):
    """Status still 'running', and none of the attributes a run writes at its end."""
    good_run(path)
    with h5py.File(path, "r+") as f:
        f.attrs["status"] = KILLED_STATUS
        for name in ("steps_completed", "wall_time_seconds"):
            del f.attrs[name]


def attributes_missing(path):
    good_run(path)
    with h5py.File(path, "r+") as f:
        for name in ("status", "dt", "theta_r", "input_file", "code_version"):
            del f.attrs[name]


def identity_missing(path):
    good_run(path)
    with h5py.File(path, "r+") as f:
        del f.attrs["scheme"]


def points_cut_short(path):
    good_run(path)
    cut_datasets(path, lambda f: {name: 3 for name in point_names(f) if name != "time"})


def steps_longer_than_points(path):
    good_run(path)
    cut_datasets(path, lambda f: {name: STEPS + 3 for name in step_names(f)})


def no_state(path):
    good_run(path)
    cut_datasets(path, lambda f: {name: 0 for name in f})


def stub_of_96_bytes(path):
    good_run(path)
    path.write_bytes(path.read_bytes()[:96])


def cut_in_half(path):
    good_run(path)
    data = path.read_bytes()
    path.write_bytes(data[:len(data) // 2])


def not_hdf5(path):
    path.write_text("time,energy\n0,600\n")


# kind: (make, message for a usable file (drawn, exit 0) or an unusable one (exit 2))
USABLE = {
    "killed": (killed, f"INCOMPLETE after {STEPS} steps"),
    "attributes_missing": (attributes_missing, "root attributes dt, theta_r, input_file, code_version missing"),
    "points_cut_short": (points_cut_short, "read up to step 2"),
    "steps_longer_than_points": (steps_longer_than_points, f"read up to step {STEPS}"),
}
UNUSABLE = {
    "identity_missing": (identity_missing, "root attribute 'scheme' is missing"),
    "no_state": (no_state, "no state written"),
    "stub_of_96_bytes": (stub_of_96_bytes, "cannot open as an HDF5 run file"),
    "cut_in_half": (cut_in_half, "cannot open as an HDF5 run file"),
    "not_hdf5": (not_hdf5, "cannot open as an HDF5 run file"),
}
PLOTS = {"plot_balance.py": [], "plot_temperatures.py": [], "plot_constrained.py": [],
         "plot_snapshots.py": ["--no-animation"]}


def run(script, *arguments):
    return subprocess.run([sys.executable, str(POSTPROCESS / script), *map(str, arguments)],
                          capture_output=True, text=True, timeout=120)


def run_in_process(monkeypatch, capsys, script, *arguments):
    """The script's main() as its command line runs it (through plotting.run_script), in this
    process: (exit status, stderr). An uncaught exception, which would be a traceback, fails
    the test."""
    module = importlib.import_module(script.removesuffix(".py"))
    monkeypatch.setattr(sys, "argv", [script, *map(str, arguments)])
    try:
        plotting.run_script(module.main)
        status = 0
    except SystemExit as stop:
        status = stop.code
    return status, capsys.readouterr().err


def plot_broken(directory, script, kind, kinds, runner):
    """Makes the broken file of `kind` and plots it with `runner`; returns its path, the
    expected message, the exit status and stderr."""
    make, message = kinds[kind]
    path = directory / f"{kind}.h5"
    make(path)
    status, stderr = runner(script, path, *PLOTS[script], "-o", directory / "out")
    return path, message, status, stderr


def check_usable(directory, path, message, status, stderr):
    assert status == 0, stderr
    assert f"{path}: INCOMPLETE after" in stderr and message in stderr
    assert (directory / "out.png").read_bytes().startswith(b"\x89PNG")
    caption = (directory / "out.txt").read_text()
    assert "INCOMPLETE after" in caption and message in caption


def check_unusable(directory, script, path, message, status, stderr):
    assert status == 2
    assert stderr.startswith(f"{script}: error: {path}: ") and message in stderr
    assert not (directory / "out.png").exists()


@pytest.mark.parametrize("kind", USABLE)
@pytest.mark.parametrize("script", PLOTS)
def test_a_usable_broken_file_is_drawn_and_marked_incomplete(tmp_path, monkeypatch, capsys, script, kind):
    runner = functools.partial(run_in_process, monkeypatch, capsys)
    check_usable(tmp_path, *plot_broken(tmp_path, script, kind, USABLE, runner))


@pytest.mark.parametrize("kind", UNUSABLE)
@pytest.mark.parametrize("script", PLOTS)
def test_an_unusable_file_is_named_with_exit_status_2(tmp_path, monkeypatch, capsys, script, kind):
    runner = functools.partial(run_in_process, monkeypatch, capsys)
    check_unusable(tmp_path, script, *plot_broken(tmp_path, script, kind, UNUSABLE, runner))


@pytest.mark.parametrize("script", PLOTS)
def test_the_command_line_shows_no_traceback(tmp_path, script):
    """The same through `python postprocess/SCRIPT.py`, for one usable and one unusable kind."""
    def runner(*arguments):
        result = run(*arguments)
        assert "Traceback" not in result.stderr
        return result.returncode, result.stderr

    (tmp_path / "killed").mkdir()
    check_usable(tmp_path / "killed", *plot_broken(tmp_path / "killed", script, "killed", USABLE, runner))
    (tmp_path / "stub").mkdir()
    check_unusable(tmp_path / "stub", script,
                   *plot_broken(tmp_path / "stub", script, "stub_of_96_bytes", UNUSABLE, runner))


def test_summary_prints_what_broken_files_hold_and_names_the_unusable_ones(tmp_path):
    usable = {}
    for kind, (make, _) in USABLE.items():
        usable[kind] = tmp_path / f"{kind}.h5"
        make(usable[kind])
    unusable = {}
    for kind, (make, _) in UNUSABLE.items():
        unusable[kind] = tmp_path / f"{kind}.h5"
        make(unusable[kind])
    complete = good_run(tmp_path / "complete.h5")
    result = run("summarize_runs.py", complete, *usable.values(), *unusable.values(), "--markdown")
    assert result.returncode == 2 and "Traceback" not in result.stderr
    table = [[cell.strip().replace("\\|", "|") for cell in re.split(r"(?<!\\)\|", line.strip()[1:-1])]
             for line in result.stdout.splitlines()]
    header = table[0]
    rows = {row[0]: dict(zip(header, row)) for row in table[2:]}
    assert rows["complete"]["status"] == "complete" and rows["complete"]["steps"] == str(STEPS)
    assert rows["killed"]["status"] == f"INCOMPLETE after {STEPS} steps ({KILLED_STATUS})"
    assert rows["killed"]["wall [s]"] == "-"                        # no wall time: the run never ended
    assert rows["killed"]["energy balance"] == rows["complete"]["energy balance"]
    status = rows["attributes_missing"]["status"]
    assert status.startswith("INCOMPLETE") and "incomplete: no status" in status
    assert rows["points_cut_short"]["steps"] == "2" and "INCOMPLETE after 2 steps" in rows["points_cut_short"]["status"]
    assert f"INCOMPLETE after {STEPS} steps" in rows["steps_longer_than_points"]["status"]
    # Without its scheme the numbers are still there; the row says what is missing.
    assert "root attributes scheme missing" in rows["identity_missing"]["status"]
    assert rows["identity_missing"]["scheme"].startswith("?/")
    for kind in ("no_state", "stub_of_96_bytes", "cut_in_half", "not_hdf5"):
        assert kind not in rows
        line = next(line for line in result.stderr.splitlines() if str(unusable[kind]) in line)
        assert line.startswith(f"summarize_runs.py: error: {unusable[kind]}: ") and UNUSABLE[kind][1] in line
