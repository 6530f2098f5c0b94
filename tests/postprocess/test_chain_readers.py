"""Every reader of postprocess/ on a spring chain's file of either path (issue 39, items 5 and 9;
docs/output.md, A chain's file), against the files' own datasets read here with h5py.

The files are made by the real programs: a tiny copy of inputs/chain_rod_heat.nml (6 springs in 1D,
the temperature variable), of inputs/spring_chain_small.nml (5 springs hanging in 3D, the entropy
variable, a conserved J_z) and a planar fixed-fixed chain of 3 masses and 4 thermoelastic springs
(the internal-energy variable, no viscous strains), each run on the dense path (eme_run) and split over two ranks
(mpirun -n 2 eme_run), and a 2-case eme_ensemble study of the rod. Newton is converged to its
rounding floor so that the two paths give one trajectory (tests/e2e/test_split_runs.py).
- chain_dataset.open_chain gives the split file's snapshots and rows as they are in it, on the
  documented dims; the dense file's /state read through it is the split file's snapshots;
- summarize_runs.py summarizes a chain file as any run, its figures those of the datasets, and a
  study folder or its index as its case files, each once;
- plot_snapshots.py draws a chain at its snapshots, plot_balance.py and plot_chain_temperatures.py
  draw the files' own numbers; the other figures of the double pendulum refuse a chain file in one
  line naming the file, what it lacks and what to use.
"""
import csv
import shutil
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from conftest import BIN, namelist_text

ROOT = Path(__file__).resolve().parents[2]
POSTPROCESS = ROOT / "postprocess"
sys.path.insert(0, str(POSTPROCESS))

import plot_balance  # noqa: E402
import plot_chain_temperatures  # noqa: E402
import plot_constrained  # noqa: E402
import plot_snapshots  # noqa: E402
import plot_temperatures  # noqa: E402
import summarize_runs  # noqa: E402
from chain_dataset import open_chain  # noqa: E402
from file_checksums import seal_texts  # noqa: E402
from plotting import run_script  # noqa: E402
from synthetic_runs import write_run  # noqa: E402
from trajectory import RunFileError, read_run  # noqa: E402

MPIRUN = ["mpirun", "--allow-run-as-root", "--oversubscribe"]
SCENES = ("rod", "hanging", "span")
SPAN_SCENE = """&model
  model_name = 'spring_chain'
  links = 3
  ends = 'fixed-fixed'
  span = 4.5
  dimension = 2
  gravity = 0.0, 0.0
  spring_law = 'thermoelastic'
/
&initial
  theta = 300.0, 290.0, 280.0, 270.0
  perturbation = 'mode'
  mode_number = 1
  amplitude = 0.05
/
&integrator
  scheme = 'eme'
  thermo_variable = 'internal_energy'
  dt = 0.01
  t_end = 0.05
  newton_tol = 1.0e-30
/
&output
  file = 'OUTPUT'
/
"""


def scene_text(scene, output):
    """The namelist of a scene, cut to 5 steps of 10 ms, writing `output`, Newton to its floor."""
    if scene == "span":
        return SPAN_SCENE.replace("OUTPUT", str(output))
    if scene == "rod":
        text = (ROOT / "inputs" / "chain_rod_heat.nml").read_text()
        changes = {"links = 100": "links = 6", "50*340.0, 50*280.0": "3*340.0, 3*280.0", "t_end = 2.0": "t_end = 0.05",
                   "snapshot_every = 5": "snapshot_every = 2", "newton_tol = 1.0e-9": "newton_tol = 1.0e-30",
                   "results/chain_rod_heat.h5": str(output)}
    else:
        text = (ROOT / "inputs" / "spring_chain_small.nml").read_text()
        changes = {"t_end = 5.0": "t_end = 0.05", "newton_tol = 1.0e-10": "newton_tol = 1.0e-30",
                   "results/spring_chain_small.h5": str(output)}
    for old, new in changes.items():
        assert old in text, (scene, old)
        text = text.replace(old, new)
    return text


def run(command, status=0, timeout=300):
    result = subprocess.run([str(part) for part in command], capture_output=True, text=True, timeout=timeout)
    assert result.returncode == status, result.stderr
    return result


@pytest.fixture(scope="module")
def chain_files(tmp_path_factory):
    """{(scene, 'dense' or 'split'): path}, ('rod', 'incomplete'): a split run that Newton stopped at its
    first step (-snes_max_it 1: exit status 3), and 'study': the folder of a 2-case study of the rod."""
    if not (BIN / "eme_run").exists():
        pytest.skip(f"{BIN / 'eme_run'} is missing: run `make` first")
    folder = tmp_path_factory.mktemp("chain_files")
    files = {}
    for scene in SCENES:
        for path in ("dense", "split"):
            output = folder / f"{scene}_{path}.h5"
            namelist = folder / f"{scene}_{path}.nml"
            namelist.write_text(scene_text(scene, output))
            ranks = [*MPIRUN, "-n", "2"] if path == "split" else []
            run([*ranks, BIN / "eme_run", namelist])
            files[scene, path] = output
    namelist = folder / "rod_incomplete.nml"
    namelist.write_text(scene_text("rod", folder / "rod_incomplete.h5"))
    run([*MPIRUN, "-n", "2", BIN / "eme_run", namelist, "-snes_max_it", "1"], status=3)
    files["rod", "incomplete"] = folder / "rod_incomplete.h5"
    with h5py.File(files["rod", "split"], "r") as split, h5py.File(files["rod", "dense"], "r") as dense:
        assert "snapshots" in split and "state" not in split, "the split run did not take the split path"
        assert "state" in dense and "snapshots" not in dense, "the dense run did not take the dense path"
    study = folder / "study.nml"
    study.write_text(f"&study\n  base = 'rod_dense.nml'\n  output_dir = '{folder / 'study'}'\n/\n"
                     "&sweep field = 'dt', values = 0.01, 0.005 /\n")
    run([BIN / "eme_ensemble", study])
    files["study"] = folder / "study"
    return files


def text(value):
    return value.decode() if isinstance(value, bytes) else str(value)


# --- chain_dataset.open_chain ---------------------------------------------------------------------

@pytest.mark.parametrize("scene", SCENES)
def test_the_dataset_of_a_split_file_holds_its_snapshots_and_rows(chain_files, scene):
    path = chain_files[scene, "split"]
    chain = open_chain(path)
    with h5py.File(path, "r") as f:
        links, dimension = int(f.attrs["links"]), int(f.attrs["dimension"])
        springs = links + (text(f.attrs["ends"]) == "fixed-fixed")
        assert dict(chain.sizes) == {"time": f["time"].shape[0], "snapshot_time": f["snapshots/time"].shape[0],
                                     "mass": links, "spring": springs, "component": dimension,
                                     "balance_column": f["balance"].shape[1],
                                     **({"angular_momentum_column": f["angular_momentum"].shape[1]}
                                        if "angular_momentum" in f else {})}
        assert chain["component"].values.tolist() == ["x", "y", "z"][:dimension]
        assert chain["mass"].values.tolist() == list(range(1, links + 1))
        assert chain["q"].dims == ("snapshot_time", "mass", "component")
        assert chain["theta"].dims == ("snapshot_time", "spring")
        assert np.array_equal(chain["snapshot_time"].values, f["snapshots/time"][()])
        for k in range(f["snapshots/time"].shape[0]):
            for name in ("q", "p", "gamma", "theta"):
                if name in f["snapshots"] or name in chain:
                    assert np.array_equal(chain[name].isel(snapshot_time=k).values, f[f"snapshots/{name}"][k]), \
                        (name, k)
        # The run's own variable under a name of its own (the rows' `entropy` is the total S).
        variable = {"hanging": "entropy", "span": "internal_energy"}.get(scene)
        if variable:
            assert np.array_equal(chain[f"spring_{variable}"].values, f[f"snapshots/{variable}"][()])
        assert np.array_equal(chain["entropy"].values, f["entropy"][()])
        # Rows: per point on time; per step on the point its step ends at, NaN at the first.
        assert np.array_equal(chain["time"].values, f["time"][()])
        assert np.array_equal(chain["time"].values[1:], f["step_end_time"][()])
        assert chain["step"].values.tolist() == [0, *f["step"][()].tolist()]
        for name in ("newton_iterations", "residual_norm", "min_viscous_production", "min_link_production"):
            values = chain[name].values
            assert chain[name].dims == ("time",) and np.isnan(values[0]), name
            assert np.array_equal(values[1:], f[name][()], equal_nan=True), name
        assert chain["balance_column"].values.tolist() == text(f["balance"].attrs["columns"]).split()
        assert np.array_equal(chain["balance"].values[1:], f["balance"][()], equal_nan=True)
        assert chain.attrs["snapshot_source"] == "/snapshots" and chain.attrs["status"] == "complete"


@pytest.mark.parametrize("scene", SCENES)
def test_the_dataset_of_a_dense_file_is_that_of_the_split_file(chain_files, scene):
    with open_chain(chain_files[scene, "dense"]) as dense, open_chain(chain_files[scene, "split"]) as split:
        assert {name: size for name, size in dense.sizes.items() if name in ("mass", "spring", "component", "time")} \
            == {name: size for name, size in split.sizes.items() if name in ("mass", "spring", "component", "time")}
        assert dense.attrs["snapshot_source"] == "/state"
        with h5py.File(chain_files[scene, "dense"], "r") as f:
            # A snapshot at every point, the temperatures /temperature's.
            assert np.array_equal(dense["snapshot_time"].values, f["time"][()])
            assert np.array_equal(dense["theta"].values, f["temperature"][()])
        at_snapshots = dense.sel(snapshot_time=split["snapshot_time"].values)
        names = {name for name, variable in split.data_vars.items() if "snapshot_time" in variable.dims}
        assert names == {name for name, variable in dense.data_vars.items() if "snapshot_time" in variable.dims}
        assert names == {"rod": {"q", "p", "gamma", "theta"}, "hanging": {"q", "p", "gamma", "theta", "spring_entropy"},
                         "span": {"q", "p", "theta", "spring_internal_energy"}}[scene]
        for name in names:
            expected, got = split[name].values, at_snapshots[name].values
            assert at_snapshots[name].dims == split[name].dims
            scale = max(1.0, np.max(np.abs(expected)))
            assert np.max(np.abs(got - expected)) <= 1e-9 * scale, (name, got, expected)
        for name in ("energy", "entropy", "lyapunov"):
            assert np.allclose(dense[name].values, split[name].values, rtol=1e-10, atol=0), name
        # Each path's Newton counts its own iterations; both on time, none before the first step.
        assert dense["newton_iterations"].dims == ("time",) and np.isnan(dense["newton_iterations"].values[0])


def test_the_dataset_of_a_stopped_dense_run_holds_the_points_every_dataset_has(chain_files, tmp_path):
    # A file whose /state lost its last row (as a killed writer could leave it): every other
    # dataset is cut to the points /state holds.
    path = tmp_path / "cut.h5"
    shutil.copy(chain_files["rod", "dense"], path)
    with h5py.File(path, "r+") as f:
        state, attrs = f["state"][:-1], dict(f["state"].attrs)
        del f["state"]
        f["state"] = state
        for name, value in attrs.items():
            if name != "DIMENSION_LIST":
                f["state"].attrs[name] = value
        seal_texts(f)
        time, temperature = f["time"][()], f["temperature"][()]
    with open_chain(path) as chain:
        assert chain.sizes["time"] == chain.sizes["snapshot_time"] == len(state) == len(time) - 1
        assert np.array_equal(chain["time"].values, time[:-1])
        assert np.array_equal(chain["theta"].values, temperature[:-1])
        names = text(attrs["columns"]).split()
        assert np.array_equal(chain["q"].values[:, 2, 0], state[:, names.index("x3_x")])


def test_the_dataset_refuses_another_model_and_a_file_without_state(tmp_path):
    pendulum, _ = write_run(tmp_path / "pendulum.h5", attributes={"model_name": "double_pendulum"})
    with pytest.raises(RunFileError) as error:
        open_chain(pendulum)
    assert str(pendulum) in str(error.value) and "'double_pendulum' is not a spring chain" in str(error.value)
    empty = tmp_path / "empty.h5"
    with h5py.File(empty, "w") as handle:
        handle.attrs["model_name"] = "spring_chain"
        handle["time"] = np.zeros(2)
    with pytest.raises(RunFileError) as error:
        open_chain(empty)
    assert str(empty) in str(error.value) and "/snapshots" in str(error.value) and "/state" in str(error.value)


# --- summarize_runs.py ------------------------------------------------------------------------------

@pytest.mark.parametrize("file", [("rod", "split"), ("hanging", "split"), ("hanging", "dense")], ids="-".join)
def test_a_chain_file_is_summarized_from_its_datasets(chain_files, file):
    path = chain_files[file]
    row = summarize_runs.summarize(path)
    with h5py.File(path, "r") as f:
        energy, entropy, heat = f["energy"][()], f["entropy"][()], f["boundary_heat"][()]
        steps = int(f["step"][-1])
        assert row["steps"] == steps == int(f.attrs["steps_completed"]) == 5
        assert row["status"] == "complete"
        # A complete file's energy balance is eme_run's over every step (run_figures); the dense path
        # takes it from the points' E, the split path from the sums of the parts' differences.
        assert row["energy_drift"] == f.attrs["run_figures"][0]
        if file[1] == "dense":
            assert np.isclose(row["energy_drift"], np.max(np.abs(energy - energy[0] - heat)) / abs(energy[0]),
                              rtol=1e-6, atol=0)
        assert np.isclose(row["min_dS"], np.min(np.diff(entropy)), rtol=1e-8)
        assert row["newton_per_step"] == np.sum(f["newton_iterations"][()]) / steps
        for name in ("min_viscous_production", "min_link_production"):
            if name in f:
                values = f[name][()]
                assert row[name] == np.min(values[np.isfinite(values)]), name
            else:
                assert np.isnan(row[name]), name
        if "angular_momentum" in f:
            jz = f["angular_momentum"][:, 2]
            assert np.isclose(row["jz_drift"], np.max(np.abs(jz - jz[0])), rtol=1e-6, atol=1e-15)
            assert row["momentum"] == "J_z"
        else:
            assert np.isnan(row["jz_drift"])


def test_the_table_gives_a_chain_its_production_columns(chain_files, capsys):
    paths = [chain_files["rod", "split"], chain_files["hanging", "dense"]]
    assert summarize_runs.main([str(path) for path in paths]) == 0
    header, split_row, dense_row = (line.split("  ") for line in capsys.readouterr().out.splitlines())
    header = [cell.strip() for cell in header if cell.strip()]
    split_row, dense_row = ([cell.strip() for cell in row if cell.strip()] for row in (split_row, dense_row))
    viscous, link = header.index("min visc. prod. [W/K]"), header.index("min link prod. [W/K]")
    with h5py.File(paths[0], "r") as f:
        assert split_row[viscous] == f"{np.nanmin(f['min_viscous_production'][()]):.2e}"
        assert split_row[link] == f"{np.nanmin(f['min_link_production'][()]):.2e}"
    # The dense path records them too (since 2026-12-01).
    with h5py.File(paths[1], "r") as f:
        assert dense_row[viscous] == f"{np.nanmin(f['min_viscous_production'][()]):.2e}"
        assert dense_row[link] == f"{np.nanmin(f['min_link_production'][()]):.2e}"


def test_a_study_folder_is_summarized_as_its_case_files(chain_files, capsys, tmp_path):
    folder = chain_files["study"]
    cases = sorted(folder.glob("case_*.h5"))
    assert len(cases) == 2 and (folder / "index.h5").exists()
    tables = []
    for arguments in ([folder], [folder / "index.h5"], [*folder.glob("*.h5"), folder]):
        assert summarize_runs.main([str(argument) for argument in arguments]) == 0, arguments
        tables.append(capsys.readouterr().out)
    assert tables[0] == tables[1] == tables[2]
    lines = tables[0].splitlines()
    assert len(lines) == 3, tables[0]
    for line, case in zip(lines[1:], cases):
        with h5py.File(case, "r") as f:
            overrides, steps = text(f.attrs["study_overrides"]), int(f.attrs["steps_completed"])
        assert line.startswith(f"{folder.name}/{case.stem}") and overrides in line, (line, overrides)
        assert f"  {steps}  " in line
    # A folder without case files (an index-only study) is named, with what reads its index.
    empty = tmp_path / "index_only"
    empty.mkdir()
    assert summarize_runs.main([str(empty), str(cases[0])]) == 2
    captured = capsys.readouterr()
    assert f"{empty}: a study folder without case files" in captured.err and "study_table.py" in captured.err
    assert len(captured.out.splitlines()) == 2


# --- the figures ----------------------------------------------------------------------------------

PENDULUM_FIGURES = {
    # script: (what it lacks in a split file, what it says to use)
    plot_temperatures: ("/temperature", "plot_chain_temperatures.py"),
    plot_constrained: ("root attribute fix_length", "plot_balance.py"),
}


@pytest.mark.parametrize("path", ["split", "dense"])
@pytest.mark.parametrize("script", PENDULUM_FIGURES, ids=lambda script: script.__name__)
def test_a_figure_of_the_double_pendulum_refuses_a_chain_file(chain_files, capsys, tmp_path, script, path):
    chain = chain_files["rod", path]
    out = tmp_path / "figure"
    with pytest.raises(SystemExit) as stop:
        run_script(lambda: script.main([str(chain), "-o", str(out)]))
    assert stop.value.code == 2
    error = capsys.readouterr().err
    lacks, instead = PENDULUM_FIGURES[script]
    assert len(error.splitlines()) == 1, error
    assert f"{chain}: a spring chain's file (6 springs)" in error and f"use {instead} {chain}" in error, error
    if path == "split" or script is plot_constrained:
        assert f"it has no {lacks}" in error, error
    assert not list(tmp_path.iterdir())


def test_a_refused_chain_file_ends_the_script_in_one_line(chain_files, tmp_path):
    chain = chain_files["hanging", "split"]
    result = subprocess.run([sys.executable, str(POSTPROCESS / "plot_temperatures.py"), str(chain), "-o",
                             str(tmp_path / "figure")], capture_output=True, text=True, timeout=120)
    assert result.returncode == 2
    assert result.stderr.startswith(f"plot_temperatures.py: error: {chain}: a spring chain's file (5 springs): it "
                                    "has no /temperature") and len(result.stderr.splitlines()) == 1, result.stderr
    assert not list(tmp_path.iterdir())


@pytest.mark.drawing
@pytest.mark.parametrize("path", ["split", "dense"])
def test_the_balance_figure_draws_a_chain_files_energy(chain_files, path):
    run = read_run(chain_files["hanging", path], ["energy"], thermal_datasets=["entropy", "lyapunov"])
    figure = plot_balance.make_figure([run])
    energy_axes = figure.axes[0]
    with h5py.File(chain_files["hanging", path], "r") as f:
        x, y = energy_axes.lines[0].get_data()
        assert np.array_equal(x, f["time"][()]) and np.array_equal(y, f["energy"][()])
    plot_balance.plt.close(figure)


@pytest.mark.drawing
@pytest.mark.parametrize("path", ["split", "dense"])
def test_the_chain_temperatures_are_the_files(chain_files, tmp_path, path):
    chain = chain_files["rod", path]
    out = tmp_path / "temperatures"
    plot_chain_temperatures.main([str(chain), "-o", str(out)])
    with open(out.with_suffix(".csv")) as handle:
        table = np.array(list(csv.reader(handle))[1:], dtype=float)
    with h5py.File(chain, "r") as f:
        time, theta = ((f["snapshots/time"][()], f["snapshots/theta"][()]) if path == "split"
                       else (f["time"][()], f["temperature"][()]))
    assert table.shape == (time.size, 7)
    assert np.allclose(table[:, 0], time, rtol=1e-8, atol=0) and np.allclose(table[:, 1:], theta, rtol=1e-8, atol=0)


@pytest.mark.drawing
def test_a_stopped_split_run_is_read_and_drawn_as_far_as_it_goes(chain_files, tmp_path, capsys):
    path = chain_files["rod", "incomplete"]
    with h5py.File(path, "r") as f:
        status, snapshots = f.attrs["status"], f["snapshots/time"].shape[0]
    assert status.startswith("incomplete") and snapshots == 1
    with open_chain(path) as chain:
        assert chain.sizes["snapshot_time"] == 1 and chain.sizes["time"] == 1 and chain.attrs["status"] == status
    assert summarize_runs.summarize(path)["status"].startswith(f"INCOMPLETE after 0 steps ({status}")
    out = tmp_path / "temperatures"
    plot_chain_temperatures.main([str(path), "-o", str(out)])
    mark = f"{path}: INCOMPLETE, drawn as far as it goes (status: {status})"
    assert mark in capsys.readouterr().err and mark in out.with_suffix(".txt").read_text()


def chain_states(path):
    """(times, q as time x mass x component, theta as time x spring) of a chain's file, read here:
    a split file's /snapshots, a dense file's /state columns x<i>_<c> (and /temperature)."""
    with h5py.File(path, "r") as f:
        if "snapshots" in f:
            return f["snapshots/time"][()], f["snapshots/q"][()], f["snapshots/theta"][()]
        names = text(f["state"].attrs["columns"]).split()
        masses, dimension = int(f.attrs["links"]), int(f.attrs["dimension"])
        state = f["state"][()]
        q = np.stack([np.stack([state[:, names.index(f"x{i}_{c}")] for c in "xyz"[:dimension]], axis=1)
                      for i in range(1, masses + 1)], axis=1)
        return f["time"][()], q, f["temperature"][()]


@pytest.mark.drawing
@pytest.mark.parametrize("path", ["split", "dense"])
@pytest.mark.parametrize("scene", SCENES)
def test_the_snapshots_draw_a_chain_as_its_file_holds_it(chain_files, scene, path):
    times, q, theta = chain_states(chain_files[scene, path])
    chosen = sorted({0, len(times) // 2, len(times) - 1})
    run = plot_snapshots.read_drawn_run(chain_files[scene, path])
    figure = plot_snapshots.make_figure([run], [times[k] for k in chosen])
    planes = [(0, 2), (0, 1)] if q.shape[2] == 3 else [(0, 1)]
    with h5py.File(chain_files[scene, path], "r") as f:
        # A fixed-fixed chain's last spring ends at the second support, x = span.
        far = [[float(f.attrs["span"]), 0.0, 0.0]] if text(f.attrs["ends"]) == "fixed-fixed" else np.zeros((0, 3))
    panels = np.array(figure.axes[:len(planes) * len(chosen)]).reshape(len(planes), len(chosen))
    for row, (i, j) in enumerate(planes):
        for column, k in enumerate(chosen):
            ax = panels[row, column]
            nodes = np.vstack([np.zeros((1, 3)), np.pad(q[k], ((0, 0), (0, 3 - q.shape[2]))), far])[:, [i, j]]
            springs = ax.collections[0]
            # Spring a joins node a-1 to node a (the support is node 0), coloured by theta_a.
            assert np.array_equal(np.array(springs.get_segments()), np.stack([nodes[:-1], nodes[1:]], axis=1))
            assert np.array_equal(springs.get_array(), theta[k])
            masses = next(line for line in ax.lines if line.get_marker() == "o")
            assert np.array_equal(np.column_stack(masses.get_data()), nodes[1:1 + q.shape[1]])
            assert masses.get_visible()
    legend = [text.get_text() for text in figure.legends[0].get_texts()]
    assert "masses $m_i$ at $q_i$" in legend and "path of the last mass so far" in legend
    plot_snapshots.plt.close(figure)


@pytest.mark.drawing
def test_a_long_1d_chain_is_drawn_flat_without_mass_markers(tmp_path):
    """The rod of 100 springs: its masses' markers (every 4 cm) hid the springs' colours, and its
    line sat in a square panel with a vertical scale of metres that meant nothing. Beyond 20
    masses the markers are not drawn (the legend says so); a 1D row is flat, without y ticks."""
    output = tmp_path / "rod.h5"
    text = (ROOT / "inputs" / "chain_rod_heat.nml").read_text()
    for old, new in {"t_end = 2.0": "t_end = 0.02", "results/chain_rod_heat.h5": str(output)}.items():
        assert old in text
        text = text.replace(old, new)
    (tmp_path / "rod.nml").write_text(text)
    run([BIN / "eme_run", tmp_path / "rod.nml"])
    figure = plot_snapshots.make_figure([plot_snapshots.read_drawn_run(output)], [0.0, 0.02])
    figure.canvas.draw()       # the layout, as saving does
    for ax in figure.axes[:2]:
        masses = next(line for line in ax.lines if line.get_marker() == "o")
        assert len(masses.get_xdata()) == 100 and not masses.get_visible()
        assert len(ax.get_yticks()) == 0
        width, height = ax.get_window_extent().width, ax.get_window_extent().height
        assert height < 0.5 * width, (width, height)
    legend = [text.get_text() for text in figure.legends[0].get_texts()]
    assert "masses $m_i$ at $q_i$ (not drawn for more than 20)" in legend, legend
    plot_snapshots.plt.close(figure)


DENSE_MINIMA_SCENE = {"model": {"model_name": "spring_chain", "links": 4, "dimension": 2,
                                "conductivity": [2.0, 3.0, 4.0]},
                      "initial": {"theta": [300.0, 320.0, 290.0, 310.0], "perturbation": "random"},
                      "integrator": {"scheme": "eme", "dt": 0.01, "t_end": 0.05, "newton_tol": 1.0e-30}}


def test_a_dense_chain_file_records_the_production_minima_of_the_split_one(tmp_path):
    """A dense chain run records `/min_viscous_production` and `/min_link_production` (the model's
    own step figures) as the split path does: the link minimum is, to rounding, the formula typed
    here, min_a kappa_a (Theta_a - Theta_(a+1))^2/(Theta_a Theta_(a+1)), of the file's
    `/scheme_temperature` (the step's discrete temperatures); both minima are the split run's of
    the same chain to 1e-8 and never negative. They were missing from dense files."""
    files = {}
    for path, options in (("dense", []), ("split", ["-eme_split"])):
        groups = {**DENSE_MINIMA_SCENE, "output": {"file": str(tmp_path / f"{path}.h5")}}
        (tmp_path / f"{path}.nml").write_text(namelist_text(groups))
        run([BIN / "eme_run", tmp_path / f"{path}.nml", *options])
        files[path] = tmp_path / f"{path}.h5"
    with h5py.File(files["dense"], "r") as dense, h5py.File(files["split"], "r") as split:
        assert "state" in dense and "snapshots" in split
        theta, kappa = dense["scheme_temperature"][()], np.array([2.0, 3.0, 4.0])
        typed = np.min(kappa * (theta[:, :-1] - theta[:, 1:]) ** 2 / (theta[:, :-1] * theta[:, 1:]), axis=1)
        np.testing.assert_allclose(dense["min_link_production"][()], typed, rtol=1e-12)
        for name in ("min_viscous_production", "min_link_production"):
            assert dense[name].shape == (5,) and np.all(dense[name][()] >= 0.0), name
            np.testing.assert_allclose(dense[name][()], split[name][()], rtol=1e-8, err_msg=name)
