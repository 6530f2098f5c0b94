"""Shared helpers for the Python tests: write namelists and run the drivers."""
import os
import subprocess
from pathlib import Path

import h5py
import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
# EME_BIN_DIR points the tests at other builds of the drivers (default: this checkout's).
BIN = Path(os.environ.get("EME_BIN_DIR", ROOT / "build" / "bin"))


def pytest_configure(config):
    # make check's quick set leaves these out (tests/run_tests.py --quick); make test runs them.
    config.addinivalue_line("markers", "drawing: draws a figure or checks a drawn one (make test only, not make check)")


def namelist_text(groups):
    """Namelist text from {'integrator': {'dt': 0.1, 'scheme': 'eme'}, ...}."""

    def value(v):
        if isinstance(v, str):
            return f"'{v}'"
        if isinstance(v, bool):
            return ".true." if v else ".false."
        if isinstance(v, (list, tuple, np.ndarray)):
            return ", ".join(value(x) for x in v)
        return repr(float(v)) if isinstance(v, float) else str(v)

    lines = []
    for group, fields in groups.items():
        lines.append(f"&{group}")
        lines.extend(f"  {name} = {value(v)}" for name, v in fields.items())
        lines.append("/")
    return "\n".join(lines) + "\n"


def read_namelist(path):
    """The groups of a namelist file as the project's inputs write them (one field a line,
    `name = value[, value ...]`, comments after `!`), as {'group': {'field': value}}: texts
    without their quotes, logicals as bool, integers (no point, no exponent) as int, other numbers
    as float, several values as a list.
    The inverse of namelist_text for such files, so a test can run a shipped input with changes."""
    groups, group = {}, None
    for line in Path(path).read_text().splitlines():
        line = line.split("!", 1)[0].strip()
        if not line:
            continue
        if line.startswith("&"):
            group = groups.setdefault(line[1:].strip().lower(), {})
        elif line == "/":
            group = None
        else:
            name, text = (part.strip() for part in line.split("=", 1))
            values = [v.strip() for v in text.split(",")]
            if values[0][:1] in "'\"":
                group[name.lower()] = values[0][1:-1]
            elif values[0].lower() in (".true.", ".false."):
                group[name.lower()] = values[0].lower() == ".true."
            else:
                numbers = [int(v) if v.lstrip("+-").isdigit() else float(v.lower().replace("d", "e")) for v in values]
                group[name.lower()] = numbers[0] if len(numbers) == 1 else numbers
    return groups


def run_eme(directory, name, groups, *options, timeout=300):
    """Runs eme_run on a namelist built from `groups`; the output goes to directory/name.h5.

    Returns (completed process, path of the HDF5 file)."""
    directory = Path(directory)
    output = directory / f"{name}.h5"
    groups = {key: dict(fields) for key, fields in groups.items()}
    groups.setdefault("output", {})["file"] = str(output)
    namelist = directory / f"{name}.nml"
    namelist.write_text(namelist_text(groups))
    result = subprocess.run([str(BIN / "eme_run"), str(namelist), *options],
                            capture_output=True, text=True, timeout=timeout)
    return result, output


def read_run(path):
    """Datasets and attributes of a run file as plain numpy arrays and Python values."""
    with h5py.File(path, "r") as f:
        data = {name: f[name][()] for name in f}
        data["attrs"] = dict(f.attrs)
    return data


@pytest.fixture(scope="session")
def eme_run_binary():
    binary = BIN / "eme_run"
    assert binary.exists(), f"{binary} is missing: run `make` first"
    return binary
