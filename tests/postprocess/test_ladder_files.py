"""The scripts on every rung of the spring ladder (issue 32; docs/formulation.md section 9), from
synthetic files laid out as the rungs' files are (synthetic_runs.write_ladder_run): planar
positions (q1_x q1_y ...), no gamma column, no /temperature, /entropy or /lyapunov (elastic
springs), no /angular_momentum (a planar scene under gravity), the planar scalar J. Before the
change 29 of these 41 failed (a missing dataset, column or attribute, or EME_none); the spatial
thermal rungs, laid out as today's files, passed then as now."""
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "postprocess"))

import plot_balance  # noqa: E402
import plot_constrained  # noqa: E402
import plot_snapshots  # noqa: E402
import plot_temperatures  # noqa: E402
import study_analysis  # noqa: E402
import study_plots  # noqa: E402
import summarize_runs  # noqa: E402
import trajectory  # noqa: E402
from synthetic_runs import constraint_attributes, ladder_columns, write_ladder_run, write_run  # noqa: E402

RUNGS = [(law, dimension, gravity) for law in ("elastic", "thermoelastic", "thermoviscoelastic")
         for dimension in (2, 3) for gravity in ((False, True) if dimension == 2 else (True,))]


def rung_id(rung):
    law, dimension, gravity = rung
    return f"{law}-{dimension}d" + ("-gravity" if gravity else "")


@pytest.mark.parametrize("rung", RUNGS, ids=rung_id)
def test_positions_are_read_in_the_runs_dimension(tmp_path, rung):
    """m1 at q1, m2 at q1 + q2, with two columns for a planar run and three for a spatial one."""
    law, dimension, gravity = rung
    path, data = write_ladder_run(tmp_path / "run.h5", law, dimension, gravity)
    run = trajectory.read_run(path, ["state"])
    m1, m2 = trajectory.mass_positions(run)
    columns = ladder_columns(law, dimension)
    q1 = data["state"][:, [columns.index(f"q1_{axis}") for axis in "xyz"[:dimension]]]
    q2 = data["state"][:, [columns.index(f"q2_{axis}") for axis in "xyz"[:dimension]]]
    assert m1.shape == (5, dimension), m1.shape
    np.testing.assert_array_equal(m1, q1)
    np.testing.assert_array_equal(m2, q1 + q2)


@pytest.mark.parametrize("thermo_variable", [True, False], ids=["variable none", "no variable attribute"])
def test_an_elastic_run_is_named_by_its_scheme_alone(tmp_path, thermo_variable):
    """No thermal unknowns, no subscript: EME, not EME_none; a missing thermo_variable is not an
    error for a file without /temperature (it still is for one with it)."""
    path, _ = write_ladder_run(tmp_path / "run.h5", thermo_variable=thermo_variable)
    run = trajectory.read_run(path, ["energy"])
    assert (run.name, run.short_label) == ("EME", "EME"), (run.name, run.short_label)
    assert not run.incomplete, run.problems


def test_a_thermal_run_without_thermo_variable_is_still_refused(tmp_path):
    path, _ = write_run(tmp_path / "run.h5", drop=["thermo_variable"])
    with pytest.raises(trajectory.RunFileError, match="thermo_variable"):
        trajectory.read_run(path, ["energy"])


@pytest.mark.parametrize("rung, expected", [
    (("elastic", 2, False), "J"), (("thermoelastic", 3, True), "J_z"), (("elastic", 2, True), None)],
    ids=["planar J", "spatial J_z", "none under planar gravity"])
def test_the_conserved_momentum_is_the_scenes(tmp_path, rung, expected):
    """momentum_drift follows the root attribute conserved_momentum: the planar J, J_z, or none."""
    path, data = write_ladder_run(tmp_path / "run.h5", *rung)
    run = trajectory.read_run(path, [], optional=["angular_momentum"])
    name, drift = trajectory.momentum_drift(run)
    assert name == expected, name
    if name is None:
        assert drift is None
        return
    column = {"J": 0, "J_z": 2}[name]
    values = data["angular_momentum"][:, column]
    np.testing.assert_array_equal(drift, values - values[0])


@pytest.mark.parametrize("rung", RUNGS, ids=rung_id)
def test_summary_row_of_every_rung(tmp_path, rung):
    """summarize_runs: the energy balance of every rung; dS and dV only with an entropy; the drift of
    the scene's conserved momentum (the planar J, or J_z), '-' where it has none; the scheme without
    a variable for elastic springs."""
    law, dimension, gravity = rung
    path, data = write_ladder_run(tmp_path / f"{rung_id(rung)}.h5", law, dimension, gravity)
    row = summarize_runs.summarize(path)
    energy = data["energy"]
    assert row["energy_drift"] == pytest.approx(np.max(np.abs(energy - energy[0])) / energy[0], rel=1e-12)
    if law == "elastic":
        assert np.isnan(row["min_dS"]) and np.isnan(row["max_dV"]), row
        assert row["run"] == "eme/gonzalez", row["run"]
    else:
        assert row["min_dS"] == pytest.approx(0.01) and row["max_dV"] == pytest.approx(np.diff(data["lyapunov"]).max())
    if dimension == 2 and gravity:
        assert np.isnan(row["jz_drift"]), row["jz_drift"]
    else:
        values = data["angular_momentum"][:, 0 if dimension == 2 else 2]
        assert row["jz_drift"] == pytest.approx(np.max(np.abs(values - values[0])), rel=1e-12), row["jz_drift"]


def test_the_table_titles_follow_the_runs(tmp_path, capsys):
    """Elastic planar runs alone: no dS and dV columns, the momentum column titled J; with a
    spatial run beside them the momentum column is 'J (conserved)' and dS, dV come back."""
    planar, _ = write_ladder_run(tmp_path / "planar.h5", "elastic", 2, False)
    assert summarize_runs.main([str(planar)]) == 0
    header = capsys.readouterr().out.splitlines()[0]
    assert "J drift [J s]" in header and "min dS" not in header and "max dV" not in header, header
    spatial, _ = write_ladder_run(tmp_path / "spatial.h5", "thermoelastic", 3, True)
    assert summarize_runs.main([str(planar), str(spatial)]) == 0
    header = capsys.readouterr().out.splitlines()[0]
    assert "J (conserved) drift [J s]" in header and "min dS [J/K]" in header and "max dV [J]" in header, header
    spatial_only = summarize_runs.main([str(spatial)])
    header = capsys.readouterr().out.splitlines()[0]
    assert spatial_only == 0 and "Jz drift [J s]" in header, header


@pytest.mark.parametrize("rung", RUNGS, ids=rung_id)
def test_every_plot_script_draws_every_rung(tmp_path, rung):
    """plot_balance, plot_snapshots and (where the rung has temperatures or a momentum)
    plot_temperatures write their PNG and PDF; plot_balance draws only the rows the rung has."""
    law, dimension, gravity = rung
    path, _ = write_ladder_run(tmp_path / "run.h5", law, dimension, gravity)
    for name, written in (
            ("balance", plot_balance.main([str(path), "-o", str(tmp_path / "balance")])),
            ("snapshots", plot_snapshots.main([str(path), "--no-animation", "-o", str(tmp_path / "snapshots")]))):
        assert all(Path(p).stat().st_size > 0 for p in written[:2]), name
    if law == "elastic" and dimension == 2 and gravity:
        with pytest.raises(trajectory.RunFileError, match="neither temperatures nor a conserved momentum"):
            plot_temperatures.main([str(path), "-o", str(tmp_path / "temperatures")])
    else:
        written = plot_temperatures.main([str(path), "-o", str(tmp_path / "temperatures")])
        assert all(Path(p).stat().st_size > 0 for p in written[:2])


def test_plot_balance_rows_are_the_quantities_some_run_has(tmp_path):
    """An elastic run alone: E only; beside a thermal run: E, S, V, the elastic run in E's row only."""
    elastic, _ = write_ladder_run(tmp_path / "elastic.h5", "elastic", 2, False)
    thermal, _ = write_ladder_run(tmp_path / "thermal.h5", "thermoelastic", 2, False)
    runs = [trajectory.read_run(p, ["energy"], optional=["entropy", "lyapunov"]) for p in (elastic, thermal)]
    fig = plot_balance.make_figure(runs[:1])
    assert len(fig.axes) == 2, len(fig.axes)
    fig = plot_balance.make_figure(runs)
    assert len(fig.axes) == 6, len(fig.axes)
    assert len(fig.axes[0].lines) == 2 and len(fig.axes[2].lines) == 1, (len(fig.axes[0].lines), len(fig.axes[2].lines))


def test_a_planar_snapshot_has_one_plane_and_plain_springs(tmp_path):
    """A planar elastic run: one row of panels (x-y, y vertical), springs in one colour, no colour bar;
    the springs end at the masses' positions."""
    path, data = write_ladder_run(tmp_path / "run.h5", "elastic", 2, False)
    run = trajectory.read_run(path, ["state"], optional=["temperature"])
    fig = plot_snapshots.make_figure([run], [0.0, 0.2])
    panels = [ax for ax in fig.axes if ax.get_visible() and ax.get_label() != "<colorbar>"]
    assert len(panels) == 2, len(panels)
    assert panels[0].get_ylabel() == "plane\ny [m]"
    m1, m2 = trajectory.mass_positions(run)
    segments = panels[0].collections[0].get_segments()
    np.testing.assert_allclose(segments[1], [m1[0], m2[0]])


def test_constrained_plot_takes_an_elastic_run(tmp_path):
    """plot_constrained on an elastic run with the length constraint: E drawn, no S and V."""
    path, _ = write_ladder_run(tmp_path / "run.h5", "elastic", 2, False)
    with h5py.File(path, "r+") as f:
        for name, value in constraint_attributes(True, False).items():
            f.attrs[name] = value
    written = plot_constrained.main([str(path), "-o", str(tmp_path / "constrained")])
    assert all(Path(p).stat().st_size > 0 for p in written[:2])


@pytest.mark.parametrize("law", ["elastic", "thermoelastic"])
def test_a_final_point_of_every_rung_for_the_work_precision_errors(tmp_path, law):
    """study_analysis.final_point: the planar mechanical columns (no gamma), the temperatures
    where the rung has them (none for elastic springs, which then need no theta_ref), and the
    error between two such points."""
    path, data = write_ladder_run(tmp_path / "a.h5", law, 2, False)
    with h5py.File(path, "r+") as f:
        if law != "elastic":
            f.attrs["theta_ref"] = 300.0
    point = study_analysis.final_point(path)
    assert point.columns == tuple(ladder_columns("elastic", 2)), point.columns
    assert point.temperatures.size == (0 if law == "elastic" else 2)
    assert study_analysis.state_error(point, point) == 0.0


def test_stability_cells_of_elastic_springs_need_no_temperature(tmp_path):
    """An elastic study's index has no temperatures (min_temperature NaN) and no V (max dV NaN):
    its complete cases are judged by the energy alone, not counted non-physical."""
    text = "&model\n  spring_law = 'elastic'\n/\n&integrator\n  t_end = 20.0\n/\n&initial\n  p2 = -1.0, 1.0\n/\n"
    rows = [{"scheme": "eme", "thermo_variable": "none", "dt": dt, "status": "complete", "case": case,
             "energy_drift": drift, "max_lyapunov_increment": float("nan"), "min_temperature": float("nan"),
             "halved_steps": 0, "steps_completed": 10, "index": tmp_path / "index.h5", "case_1_input": text}
            for case, (dt, drift) in enumerate([(0.01, 1e-14), (0.1, 1e-3)], start=1)]
    grid = study_analysis.stability_map(rows)
    outcomes = [study_analysis.OUTCOMES[code] for code in grid["outcome"][0]]
    assert outcomes == ["kept", "energy"], outcomes
    assert grid["temperatures_checked"] == 0
    label = study_plots.integrators.label("eme")
    assert (study_plots.plain_name("eme", "none"), study_plots.plain_name("eme", "entropy")) == (label, f"{label}_s")


def test_the_ladders_stability_scenes_join_the_map_when_their_studies_exist(tmp_path):
    """The pendulum's map: paper and harder scene always; the elastic and Romero's scenes once
    make study has their indexes (stability_gonzalez_elastic, stability_romero_thermoelastic)."""
    assert [scene for scene, _ in study_analysis.stability_scenes(tmp_path, "pendulum")] == ["paper", "hard"]
    for folder in ("stability_gonzalez_elastic", "stability_romero_thermoelastic"):
        (tmp_path / folder).mkdir()
        (tmp_path / folder / "index.h5").write_bytes(b"")
    scenes = study_analysis.stability_scenes(tmp_path, "pendulum")
    assert scenes[2:] == [("gonzalez", "stability_gonzalez_elastic"), ("romero", "stability_romero_thermoelastic")]
    assert all(scene in study_plots.SCENE_TITLES for scene, _ in scenes)
