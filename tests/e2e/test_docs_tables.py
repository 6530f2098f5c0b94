"""The reference tables of the docs against the code, both ways: every group and field that
`eme_run --help` (every model's) and `eme_ensemble --help` list has a row in docs/input.md, with
the unit the help gives, and every row there is a field of the help; every dataset and root
attribute of the run files of a set of short runs (EME, adaptive EME, relaxed and CVODE schemes,
PETSc TS, constraints, the gas containers, elastic springs, a study's case, a run stopped by its
step budget, a relaxed run warned for its accuracy) has a row in docs/output.md's tables, and
every row there names something one of those files holds.

A new field, dataset or attribute needs only its row. In docs/input.md a model's own groups are
marked with its model_name (`&model` (`gas_containers`)); unmarked ones are the default model's.
In docs/output.md's tables, the first cell's names count (`/name` for datasets); `<dataset>` and
`<attribute>` stand for a dataset or an attribute of the same file, `<field>` for any field of
`eme_run --help`, any other `<...>` for a word, and `*` for any text."""
import re
import subprocess
from pathlib import Path

import h5py
import pytest

from conftest import BIN, ROOT, read_namelist, run_eme

DOCS = ROOT / "docs"
DEFAULT_MODEL = "double_pendulum"


# ---------------------------------------------------------------------------------- the tables


def markdown_tables(path):
    """Every table of a markdown file as (header cells, rows of cells)."""
    tables, current = [], None
    for line in Path(path).read_text().splitlines():
        if line.startswith("|"):
            cells = [cell.strip() for cell in line.strip().strip("|").split("|")]
            if current is None:
                current = (cells, [])
                tables.append(current)
            elif not set("".join(cells)) <= set("-: "):
                current[1].append(cells)
        else:
            current = None
    return tables


def table_with(path, header):
    """The rows of the table whose header's cells start with `header`."""
    found = [rows for cells, rows in markdown_tables(path) if cells[:len(header)] == header]
    assert len(found) == 1, f"{path}: {len(found)} tables with the header {header}"
    return found[0]


def input_rows(header_first="group"):
    """{(model or None, group): {field: unit}} of each table of docs/input.md: a group cell
    `&group` (`model`) belongs to that model, an empty one continues the row above."""
    documented = {}
    for cells, rows in markdown_tables(DOCS / "input.md"):
        if cells[:2] != [header_first, "field"]:
            continue
        key = None
        for group_cell, field_cell, unit, *_ in rows:
            if group_cell:
                group = re.match(r"`&(\w+)`", group_cell).group(1)
                model = re.search(r"\(`(\w+)`\)", group_cell)
                key = (model.group(1) if model else None, group)
            for field in re.findall(r"`(\w+)", field_cell):
                assert field not in documented.setdefault(key, {}), f"docs/input.md: {key} {field} twice"
                documented[key][field] = unit
    return documented


def help_fields(program):
    """{(model or None, group): {field: its help text}} of `program --help`: None for the groups
    of every model (and eme_ensemble's)."""
    result = subprocess.run([str(BIN / program), "--help"], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    listed, model, key = {}, None, None
    for line in result.stdout.splitlines():
        if line.startswith("Integrators ("):
            break
        heading = re.match(r"Model '(\w+)'", line)
        if heading or line.startswith("Every model:"):
            model = heading.group(1) if heading else None
            continue
        group = re.fullmatch(r"  &(\w+)", line)
        if group:
            key = (model, group.group(1))
            listed[key] = {}
            continue
        field = re.match(r"    (\w+) +(.*)", line)
        if key and field:
            listed[key][field.group(1)] = field.group(2)
    return listed


@pytest.fixture(scope="module")
def run_help():
    return help_fields("eme_run")


def unit_of(text):
    """The unit a help text gives in brackets ([kg], [J/(K s)]), or None."""
    found = re.findall(r"\[([^\[\],]+)\]", text)
    return found[-1] if found else None


def compare_fields(documented, listed):
    for key in sorted(set(documented) | set(listed), key=str):
        docs, helped = documented.get(key, {}), listed.get(key, {})
        where = f"&{key[1]}" + (f" of {key[0]}" if key[0] else "")
        assert set(helped) <= set(docs), f"docs/input.md lacks rows for {where}: {sorted(set(helped) - set(docs))}"
        assert set(docs) <= set(helped), f"docs/input.md has rows --help does not list ({where}): " \
                                         f"{sorted(set(docs) - set(helped))}"
        for field, text in helped.items():
            unit = unit_of(text)
            if unit is not None:
                assert docs[field] == unit, f"{where} {field}: docs/input.md says [{docs[field]}], --help [{unit}]"


def test_input_md_lists_every_field_of_eme_run_help(run_help):
    # The default model's groups are unmarked in docs/input.md; --help names every model.
    listed = {(None if model == DEFAULT_MODEL else model, group): fields for (model, group), fields in run_help.items()}
    compare_fields({key: fields for key, fields in input_rows().items() if key[1] not in ("study", "sweep")}, listed)


def test_input_md_lists_every_field_of_eme_ensemble_help():
    study = {key: fields for key, fields in input_rows().items() if key[1] in ("study", "sweep")}
    compare_fields(study, help_fields("eme_ensemble"))


# --------------------------------------------------------------------------------- run files


def scenes():
    inputs = ROOT / "inputs"
    short = {"t_end": 0.3}
    return {
        "eme": {"integrator": short},
        "adaptive": {"integrator": {**short, "tolerance": 1e-4}},
        "relaxed": {"integrator": {**short, "scheme": "relaxed_rk4"}},
        "relaxed_adaptive": {"integrator": {**short, "scheme": "relaxed_dp853", "tolerance": 1e-6}},
        "cvode": {"integrator": {**short, "scheme": "cvode_bdf", "tolerance": 1e-6}},
        "ts": {"integrator": {**short, "scheme": "ts_rk5dp", "tolerance": 1e-6}},
        "constrained": {"integrator": short, "constraints": {"fix_length": True, "fix_temperature": True}},
        "budget": {"integrator": {**short, "tolerance": 1e-4, "max_steps": 3}},
        "gas": {**read_namelist(inputs / "gas_containers.nml"), "integrator": {"t_end": 0.3, "dt": 0.1}},
        "elastic": {**read_namelist(inputs / "gonzalez_elastic.nml"), "integrator": {"t_end": 0.1, "dt": 0.02}},
        # a chain of five springs on the dense path: its metric scales as one attribute of a row per spring
        "chain": {**read_namelist(inputs / "spring_chain_small.nml"),
                  "integrator": {"thermo_variable": "entropy", "t_end": 0.02, "dt": 0.01}},
        # relaxed_rk4 halves steps of 0.15 s of the thermoelastic scene: the file has `warnings`.
        "warned": {**read_namelist(inputs / "romero_thermoelastic.nml"),
                   "integrator": {"scheme": "relaxed_rk4", "thermo_variable": "entropy", "dt": 0.15, "t_end": 0.3}},
    }


def file_names(path):
    with h5py.File(path, "r") as f:
        return set(f), set(f.attrs)


@pytest.fixture(scope="module")
def run_files(tmp_path_factory):
    """{run: (dataset names, attribute names)} of the short runs and of a one-case study's case."""
    folder = tmp_path_factory.mktemp("docs_tables")
    files = {}
    for name, groups in scenes().items():
        groups = {group: dict(fields) for group, fields in groups.items()}
        groups.pop("output", None)
        result, path = run_eme(folder, name, groups)
        assert result.returncode in (0, 3), result.stderr
        files[name] = file_names(path)
    study = folder / "study.nml"
    study.write_text(f"&study base = '{ROOT / 'inputs' / 'paper_fig4_eme_theta.nml'}', output_dir = "
                     f"'{folder / 'study'}' /\n&sweep field = 't_end', values = 0.3 /\n")
    result = subprocess.run([str(BIN / "eme_ensemble"), str(study)], capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout + result.stderr
    files["study case"] = file_names(folder / "study" / "case_00001.h5")
    return files


def documented_names(rows, marker=""):
    """The names of a table's first cells (those starting with `marker`), placeholders kept."""
    return [name for cells in rows for name in re.findall(rf"`{marker}([\w<>*]+)", cells[0])]


def matcher(name, names, fields):
    """A regular expression for a documented name: `<dataset>`/`<attribute>` one of `names` (the
    same file's), `<field>` a field of --help, any other `<...>` a word, `*` any text."""
    parts = []
    for piece in re.split(r"(<\w+>|\*)", name):
        if piece in ("<dataset>", "<attribute>"):
            parts.append("(?:" + "|".join(map(re.escape, sorted(names, key=len, reverse=True))) + ")")
        elif piece == "<field>":
            parts.append("(?:" + "|".join(map(re.escape, sorted(fields, key=len, reverse=True))) + ")")
        elif piece.startswith("<"):
            parts.append(r"\w+")
        elif piece == "*":
            parts.append(".*")
        else:
            parts.append(re.escape(piece))
    return re.compile("".join(parts))


def compare_names(documented, files, what, fields):
    """Every name in `files` ({run: names}) matches a documented name; every documented name
    matches a name of some file."""
    used = set()
    for run, names in files.items():
        for name in sorted(names):
            matching = [d for d in documented if matcher(d, names, fields).fullmatch(name)]
            assert matching, f"docs/output.md's table lacks the {what} {name!r} of the {run} run"
            used.update(matching)
    unused = [d for d in documented if d not in used]
    assert not unused, f"docs/output.md's table has {what}s that no run file holds: {unused}"


def test_output_md_lists_every_dataset(run_files, run_help):
    documented = documented_names(table_with(DOCS / "output.md", ["dataset"]), marker="/")
    fields = {field for group in run_help.values() for field in group}
    compare_names(documented, {run: datasets for run, (datasets, _) in run_files.items()}, "dataset", fields)


def test_output_md_lists_every_root_attribute(run_files, run_help):
    documented = documented_names(table_with(DOCS / "output.md", ["attribute"]))
    fields = {field for group in run_help.values() for field in group}
    compare_names(documented, {run: attributes for run, (_, attributes) in run_files.items()}, "attribute", fields)
