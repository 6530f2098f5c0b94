"""A study index's figure columns follow its cases' model (issue 31: momenta are optional): no
angular_momentum_drift column when no case's model conserves a momentum (the gas containers, a
planar pendulum with gravity), no min_entropy_increment, max_lyapunov_increment or min_temperature
when none has temperatures (elastic springs). A restart reads such an index back, or rebuilds it
from the case files, and the postprocess scripts (study_analysis, study_table, study_plots) read,
tabulate and draw it."""
import subprocess
import sys
from pathlib import Path

import h5py
import matplotlib
import numpy as np
import pytest

from conftest import BIN, ROOT, namelist_text

matplotlib.use("Agg")
sys.path.insert(0, str(ROOT / "postprocess"))
import study_analysis  # noqa: E402
import study_plots  # noqa: E402
import study_table  # noqa: E402

MOMENTUM = {"angular_momentum_drift"}
THERMAL = {"min_entropy_increment", "max_lyapunov_increment", "min_temperature"}
GAS = {"model": {"model_name": "gas_containers", "friction": 8.0},
       "initial": {"q": 1.0, "p": 2.0, "entropy": [1.5, 3.0]}}
# gonzalez_elastic.nml's planar elastic springs, without gravity (J kept) or with it (none kept).
ELASTIC_MODEL = {"spring_law": "elastic", "dimension": 2, "mass": [1.0, 1.0], "natural_length": [1.0, 1.0],
                 "mu_eq_const": [100.0, 100.0]}
ELASTIC_INITIAL = {"q1": [1.1, 0.0], "q2": [0.0, 1.0], "p1": [0.0, 3.0], "p2": [-1.0, 1.0]}
SCENES = {
    # scene: (groups, the model-dependent columns the index lacks)
    "gas": (GAS, MOMENTUM),
    "elastic_gravity": ({"model": {**ELASTIC_MODEL, "gravity": [0.0, -9.81]}, "initial": ELASTIC_INITIAL},
                        MOMENTUM | THERMAL),
    "elastic": ({"model": {**ELASTIC_MODEL, "gravity": [0.0, 0.0]}, "initial": ELASTIC_INITIAL}, THERMAL),
    "paper": (None, set()),
}


def base_file(tmp_path, scene):
    """The scene's base file: the paper scene as it is, else the groups with a short EME run."""
    groups, _ = SCENES[scene]
    if groups is None:
        return ROOT / "inputs" / "paper_fig4_eme_theta.nml"
    path = tmp_path / f"{scene}.nml"
    path.write_text(namelist_text({**groups, "integrator": {"scheme": "eme", "dt": 0.05, "t_end": 0.5}}))
    return path


def write_study(tmp_path, base, sweeps, index_only=False):
    path = tmp_path / "study.nml"
    path.write_text(f"&study base = '{base}', output_dir = '{tmp_path / 'out'}', combine = 'zip', "
                    f"index_only = {'.true.' if index_only else '.false.'} /\n{sweeps}")
    return path


def ensemble(study):
    result = subprocess.run([str(BIN / "eme_ensemble"), str(study)], capture_output=True, text=True, timeout=300,
                            cwd=ROOT)
    assert result.returncode == 0, result.stdout + result.stderr
    return result


def index_table(output):
    """(/cases as a structured array, {column: units})."""
    with h5py.File(output / "index.h5", "r") as f:
        cases = f["cases"][()]
        units = [u.decode() if isinstance(u, bytes) else u for u in f["cases"].attrs["column_units"]]
    assert len(units) == len(cases.dtype.names), (units, cases.dtype.names)
    return cases, dict(zip(cases.dtype.names, units))


SWEEPS = ("&sweep field = 'dt', values = 0.05, 0.1 /\n"
          "&sweep field = 't_end', values = 0.5, 0.5 /\n")


@pytest.mark.parametrize("scene", list(SCENES))
def test_the_index_has_the_figures_its_model_has(tmp_path, eme_run_binary, scene):
    """Each scene's index lacks exactly the figures its model has none of, keeps the others (with
    its units), and reads back the same on a restart and when rebuilt from the case files."""
    missing = SCENES[scene][1]
    study = write_study(tmp_path, base_file(tmp_path, scene), SWEEPS)
    ensemble(study)
    output = tmp_path / "out"
    cases, units = index_table(output)
    names = set(cases.dtype.names)
    assert not names & missing, names & missing
    assert (MOMENTUM | THERMAL) - missing <= names
    assert list(cases.dtype.names)[-2:] == ["rank", "run_count"]
    assert set(cases["status"].astype(str)) == {"complete"}
    for name in (MOMENTUM | THERMAL) - missing:
        assert np.all(np.isfinite(cases[name])), name
    if scene == "gas":
        assert units["min_temperature"] == "1" and units["min_entropy_increment"] == "1"
    if scene == "elastic":
        assert units["angular_momentum_drift"] == "J s"
    # A case file's run_figures hold NaN where the index has no column.
    with h5py.File(output / "case_00001.h5", "r") as f:
        figures = dict(zip(("energy_drift", "min_entropy_increment", "max_lyapunov_increment",
                            "angular_momentum_drift", "min_temperature"), f.attrs["run_figures"]))
    for name in missing:
        assert np.isnan(figures[name]), name
    # A restart reads the index back: nothing runs again, the rows are the same.
    ensemble(study)
    again, _ = index_table(output)
    assert again.dtype == cases.dtype
    np.testing.assert_array_equal(again["run_count"], [1, 1])
    for name in cases.dtype.names:
        if name not in ("wall_time_seconds", "solve_time_seconds", "cpu_time_seconds", "solve_cpu_time_seconds", "rank"):
            np.testing.assert_array_equal(again[name], cases[name], err_msg=name)
    # Without the index, the case files rebuild it, in the same columns.
    (output / "index.h5").unlink()
    ensemble(study)
    rebuilt, _ = index_table(output)
    assert rebuilt.dtype == cases.dtype
    np.testing.assert_array_equal(rebuilt["run_count"], [1, 1])
    np.testing.assert_array_equal(rebuilt["energy_drift"], cases["energy_drift"])


def test_an_index_only_study_resumes_from_its_journal_without_the_column(tmp_path, eme_run_binary):
    """An index-only gas study stopped after its cases' journal lines (index.h5 as at the start):
    the restart replays the journal into an index without angular_momentum_drift and runs nothing."""
    # The cases' overrides as the code spells them: from a case file of the same study with files.
    with_files = tmp_path / "with_files"
    with_files.mkdir()
    ensemble(write_study(with_files, base_file(tmp_path, "gas"), SWEEPS))
    overrides = []
    for case in (1, 2):
        with h5py.File(with_files / "out" / f"case_0000{case}.h5", "r") as f:
            overrides.append(f.attrs["study_overrides"])
    study = write_study(tmp_path, base_file(tmp_path, "gas"), SWEEPS, index_only=True)
    ensemble(study)
    output = tmp_path / "out"
    cases, _ = index_table(output)
    # The journal as a killed run leaves it: one line per result (journal_line's format), read
    # over an index.h5 whose cases are still pending.
    with h5py.File(output / "index.h5", "r+") as f:
        pending = f["cases"][()]
        pending["status"] = b"pending"
        f["cases"][...] = pending
    figures = ("steps_completed", "steps_planned", "newton_iterations", "wall_time_seconds", "solve_time_seconds",
               "cpu_time_seconds", "solve_cpu_time_seconds",
               "energy_drift", "min_entropy_increment", "max_lyapunov_increment", "angular_momentum_drift",
               "min_temperature", "halved_steps", "rejected_steps", "warned", "rank", "run_count")
    lines = ["# journal\n"]
    for row, case_overrides in zip(cases, overrides):
        values = [float("nan") if name not in cases.dtype.names else float(row[name]) for name in figures]
        lines.append("\t".join([str(row["case"]), "none", *(f"{v:.17e}" for v in values), "complete",
                                case_overrides]) + "\n")
    (output / "index.journal").write_text("".join(lines))
    result = ensemble(study)
    assert "results taken from" in result.stdout + result.stderr, result.stdout + result.stderr
    resumed, _ = index_table(output)
    assert resumed.dtype == cases.dtype
    assert set(resumed["status"].astype(str)) == {"complete"}
    np.testing.assert_array_equal(resumed["energy_drift"], cases["energy_drift"])


def test_a_sweep_that_gives_a_case_a_momentum_keeps_the_column(tmp_path, eme_run_binary):
    """The columns follow every case's model, not only the base file's: planar elastic springs with
    gravity (no momentum kept) swept to no gravity (case 1: J kept) and gravity (case 2) keep
    angular_momentum_drift, NaN for the case with gravity."""
    study = write_study(tmp_path, base_file(tmp_path, "elastic_gravity"),
                        "&sweep field = 'gravity(2)', values = 0.0, -9.81 /\n")
    ensemble(study)
    cases, units = index_table(tmp_path / "out")
    assert "angular_momentum_drift" in cases.dtype.names and not THERMAL & set(cases.dtype.names)
    assert np.isfinite(cases["angular_momentum_drift"][0]) and np.isnan(cases["angular_momentum_drift"][1])


def test_the_scripts_read_tabulate_and_draw_an_index_without_the_columns(tmp_path, eme_run_binary):
    """study_analysis reads an elastic planar study with gravity (none of the four columns) with
    NaN for them and maps its stability by the energy alone; study_table tabulates it; study_plots
    draws the map beside a gas study's (no momentum column)."""
    sweeps = ("&sweep field = 'scheme', texts = 'eme', 'eme', 'midpoint' /\n"
              "&sweep field = 'dt', values = 0.05, 0.1, 0.05 /\n")
    maps = {}
    for scene in ("elastic_gravity", "gas"):
        folder = tmp_path / scene
        folder.mkdir()
        study = folder / "study.nml"
        study.write_text(f"&study base = '{base_file(folder, scene)}', output_dir = '{folder / 'out'}', "
                         f"combine = 'zip', index_only = .true. /\n{sweeps}")
        ensemble(study)
        rows = study_analysis.read_index(folder / "out")
        assert len(rows) == 3
        for row in rows:
            for name in SCENES[scene][1]:
                assert np.isnan(row[name]), (scene, name)
        maps[scene] = study_analysis.stability_map(rows, nondimensional=scene == "gas")
        assert np.count_nonzero(maps[scene]["outcome"] >= 0) == 3      # midpoint ran at one dt only
        frame = study_table.study_frame(folder / "out" / "index.h5")
        assert not set(frame.columns) & SCENES[scene][1]
        assert list(frame["status"]) == ["complete"] * 3
        dataset = study_table.open_study(folder / "out" / "index.h5")
        assert "energy_drift" in dataset and not set(dataset.data_vars) & SCENES[scene][1]
    # Elastic springs: V = E and no temperatures, so none is held against the case.
    assert maps["elastic_gravity"]["temperatures_checked"] == 0
    assert maps["gas"]["temperatures_checked"] == 3
    figure, title, _ = study_plots.stability_figure(maps)
    figure.savefig(tmp_path / "map.png")
    assert (tmp_path / "map.png").read_bytes().startswith(b"\x89PNG")
    study_plots.plt.close("all")
