"""The output layout and the integrator registry as the drivers print them (eme_run
--output-schema, --integrators, --help) against what the files hold and what the Python scripts
read: one table each, so that a dataset, a column or an integrator cannot differ between the
Fortran side, the files and the scripts."""
import re
import subprocess
from pathlib import Path

import h5py
import pytest

from conftest import BIN, ROOT, run_eme

POSTPROCESS = ROOT / "postprocess"


def table(*options):
    """A tab-separated table printed by eme_run, as a list of dicts."""
    result = subprocess.run([str(BIN / "eme_run"), *options], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    lines = result.stdout.rstrip("\n").split("\n")
    header = lines[0].split("\t")
    return [dict(zip(header, line.split("\t"))) for line in lines[1:]]


def text(value):
    return value.decode() if isinstance(value, bytes) else str(value)


@pytest.fixture(scope="module")
def schema():
    return {row["name"]: row for row in table("--output-schema")}


@pytest.mark.parametrize("constraints", [{}, {"fix_length": True, "fix_temperature": True}])
def test_run_files_follow_the_schema(tmp_path, eme_run_binary, schema, constraints):
    """Every dataset of a run file is in the schema with its rows, units and description; every
    schema dataset is in the file (constraint datasets only with constraints); columns follow the
    schema's templates."""
    groups = {"integrator": {"t_end": 0.3}}
    if constraints:
        groups["constraints"] = constraints
    result, path = run_eme(tmp_path, "run", groups)
    assert result.returncode == 0, result.stderr
    with h5py.File(path, "r") as f:
        assert f.attrs["schema_version"] == 2
        assert text(f["energy"].attrs["description"]) == "total energy E = T + V_g + U_1 + U_2"
        for name, dataset in f.items():
            if text(dataset.attrs.get("source", "")) == "integrator":
                # the integrator's own per-step figures (its `diagnostics`, e.g. EME's substeps)
                assert text(dataset.attrs["rows"]) == "step" and dataset.shape[0] == len(f["time"]) - 1, name
                continue
            if name.endswith("_column"):
                # the dimension scale of a vector dataset's columns: their names
                assert text(dataset.attrs["CLASS"]) == "DIMENSION_SCALE", name
                owner = f[name[:-len("_column")]]
                assert [text(c) for c in dataset[()]] == text(owner.attrs["columns"]).split(), name
                continue
            assert name in schema, f"/{name} is not in eme_run --output-schema"
            spec = schema[name]
            assert text(dataset.attrs["rows"]) == spec["rows"], name
            if spec["units"] != "<columns>":
                # the model's units (model_words) where the schema names them: the pendulum's are SI
                expected = {"<E>": "J", "<S>": "J/K", "<theta>": "K"}.get(spec["units"], spec["units"])
                assert text(dataset.attrs["units"]) == expected, name
            if spec["description"].startswith("<the model says>"):
                # the model's own words (model_words), for the pendulum in its terms
                description = text(dataset.attrs["description"])
                assert description and "<" not in description, name
            elif name != "scheme_temperature":       # its description comes from the registry entry
                assert text(dataset.attrs["description"]) == spec["description"], name
            expected_rows = len(f["time"]) - (1 if spec["rows"] == "step" else 0)
            assert dataset.shape[0] == expected_rows, name
            if spec["columns"]:
                columns = text(dataset.attrs["columns"]).split()
                assert text(dataset.attrs["columns"]) == " ".join(columns), f"{name}: blanks in 'columns'"
                assert dataset.shape[1] == len(columns), name
                units = [text(u) for u in dataset.attrs["column_units"]]
                assert len(units) == len(columns) and all(u and u == u.strip() and u != "SI" for u in units), name
                # One units attribute where the columns share it; none where they differ (xarray
                # would show it as the axis label): column_units then says each.
                if len(set(units)) == 1:
                    assert text(dataset.attrs["units"]) == units[0], name
                else:
                    assert "units" not in dataset.attrs, name
                if "<" in spec["columns"]:
                    prefix = spec["columns"].split("<")[0]
                    assert all(column.startswith(prefix) for column in columns), (name, columns)
                else:
                    assert columns == spec["columns"].split(), name
            if spec["rows"] == "step" and name not in ("step", "step_end_time"):
                # Every per-step dataset has the steps' end times as its time coordinate.
                assert text(dataset.attrs["coordinates"]) == "step_end_time", name
        for name, spec in schema.items():
            if "<constraints>" in spec["columns"] and not constraints:
                assert name not in f, f"/{name} without an active constraint"
            else:
                assert name in f, f"schema dataset /{name} is missing from the file"
        if constraints:
            assert text(f["multiplier"].attrs["columns"]) == "lambda_length lambda_temperature"
            assert [text(u) for u in f["multiplier"].attrs["column_units"]] == ["N/m", "W"]
            assert [text(u) for u in f["constraint_residual"].attrs["column_units"]] == ["m^2", "K"]
            assert text(f.attrs["constraints"]) == "length, temperature"


def test_scripts_read_only_schema_datasets(schema):
    """Every dataset the scripts ask read_run for is one the code writes."""
    requested = set()
    for script in POSTPROCESS.glob("*.py"):
        for call in re.findall(r"read_run\([^\[\)]*\[([^\]]*)\]", script.read_text()):
            requested.update(re.findall(r"\"([a-z_]+)\"", call))
    assert requested, "no read_run call found: the pattern is out of date"
    assert requested <= set(schema), f"not in the schema: {sorted(requested - set(schema))}"


def test_registry_reaches_files_help_and_indexes(tmp_path, eme_run_binary):
    """The registry table equals what a run file, --help and a study index say of each integrator."""
    entries = table("--integrators")
    assert [e["name"] for e in entries][:6] == ["eme", "midpoint", "ts_midpoint", "ts_bdf2", "ts_rk4", "ts_rk5dp"]
    help_text = subprocess.run([str(BIN / "eme_run"), "--help"], capture_output=True, text=True).stdout
    for entry in entries:
        assert entry["name"] in help_text and entry["description"] in help_text
    entry = entries[3]
    result, path = run_eme(tmp_path, "one", {"integrator": {"scheme": entry["name"], "t_end": 0.3}})
    assert result.returncode == 0, result.stderr
    with h5py.File(path, "r") as f:
        assert text(f.attrs["scheme_label"]) == entry["label"]
        assert text(f.attrs["scheme_family"]) == entry["family"]
        assert text(f.attrs["scheme_description"]) == entry["description"]
    study = tmp_path / "study.nml"
    study.write_text(f"&study base = '{tmp_path / 'one.nml'}', output_dir = '{tmp_path / 'study'}' /\n"
                     "&sweep field = 't_end', values = 0.15 /\n")
    result = subprocess.run([str(BIN / "eme_ensemble"), str(study)], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    with h5py.File(tmp_path / "study" / "index.h5", "r") as f:
        rows = f["integrators"][()]
    assert [text(r["name"]) for r in rows] == [e["name"] for e in entries]
    assert [text(r["label"]) for r in rows] == [e["label"] for e in entries]
    assert [bool(r["takes_constraints"]) for r in rows] == [e["takes_constraints"] == "yes" for e in entries]
