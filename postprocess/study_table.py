#!/usr/bin/env python3
"""A study's index (OUTPUT_DIR/index.h5 of eme_ensemble) as an xarray Dataset or a pandas frame.

xarray.open_dataset(index.h5) gives one compound variable of byte strings; this helper reads the
same /cases table (its layout is unchanged) and gives:

  open_study(path)  -> xarray.Dataset
      For a study with combine = 'product' (the default), one dimension per swept field, in the
      order of the study's &sweep groups, with the swept values as its coordinate (text sweeps
      such as 'scheme' give text coordinates): ds.energy_drift.sel(scheme="eme", dt=0.1).
      A subscripted field is named with an underscore (theta(2) -> theta_2, p2(1) -> p2_1; the
      attribute `field` keeps the study's spelling). For combine = 'zip', or with
      dims="case", one dimension `case` with the swept values as coordinates along it.
      Every other field of /cases is a data variable (text decoded to str) with its unit in
      the attribute `units` (from /cases' column_units); a case that failed or has not run keeps
      its cell and its `status` ("failed: <reason>", "pending", ...), with the figures the index
      holds for it. The root attributes of index.h5 are the Dataset's attributes.
  study_frame(path) -> pandas.DataFrame
      One row per case (index: the case number), swept fields first, text decoded; the units by
      column in frame.attrs["units"].

usage: study_table.py INDEX.h5 [--case-dimension] [--csv OUT.csv]
prints the Dataset (and writes the frame as CSV).
"""
import argparse
import math
import re
import sys
from pathlib import Path

import h5py
import numpy as np
import pandas as pd
import xarray as xr

from file_checksums import DamagedFileError, check_texts

# Fields of /cases around the swept ones: 'case', 'file', the swept fields, then 'status' and the
# figures (docs/studies.md).
FIRST_FIGURE_FIELD = "status"


class StudyIndexError(Exception):
    """The file is not a study index this helper can read."""


def _text(value):
    return value.decode() if isinstance(value, bytes) else value


def _plain(value):
    """An HDF5 attribute as a str, number or list."""
    if isinstance(value, bytes):
        return value.decode()
    if isinstance(value, np.ndarray):
        return [_text(v) for v in value.tolist()] if value.dtype.kind in "SO" else value
    if isinstance(value, np.generic):
        return value.item()
    return value


def dimension_name(field):
    """theta(2) -> theta_2, p2(1) -> p2_1, dt -> dt."""
    return re.sub(r"\((\d+)\)$", r"_\1", field)


def read_index(path):
    """(records as a structured array with decoded text, field names, units by field, swept fields,
    root attributes) of an index.h5."""
    path = Path(path)
    try:
        handle = h5py.File(path, "r")
    except OSError as error:
        raise StudyIndexError(f"{path}: cannot open as a study index ({error})") from None
    with handle:
        try:
            check_texts(handle, path)
        except DamagedFileError as error:
            raise StudyIndexError(str(error)) from None
        if "cases" not in handle:
            raise StudyIndexError(f"{path}: dataset '/cases' is missing; is this an eme_ensemble index.h5?")
        table = handle["cases"]
        cases = table[()]
        names = list(cases.dtype.names or ())
        units = _plain(table.attrs.get("column_units", [""] * len(names)))
        attributes = {name: _plain(value) for name, value in handle.attrs.items()}
    for needed in ("case", "file", FIRST_FIGURE_FIELD):
        if needed not in names:
            raise StudyIndexError(f"{path}: /cases has no field '{needed}'")
    swept = names[names.index("file") + 1:names.index(FIRST_FIGURE_FIELD)]
    return cases, names, dict(zip(names, units)), swept, attributes


def _column(cases, name):
    values = cases[name]
    if values.dtype.kind == "S":
        return np.array([v.decode() for v in values], dtype=object)
    return values


def study_frame(path):
    """One row per case, indexed by case number; units in frame.attrs['units']."""
    cases, names, units, swept, attributes = read_index(path)
    columns = {name: _column(cases, name) for name in names}
    frame = pd.DataFrame(columns).set_index("case")
    frame = frame[[*swept, *(name for name in frame.columns if name not in swept)]]
    frame.attrs["units"] = {name: units[name] for name in names}
    frame.attrs["swept"] = list(swept)
    frame.attrs.update({"study": attributes.get("study", ""), "combine": attributes.get("combine", "")})
    return frame


def _grid(cases, swept):
    """The product grid: per swept field its values in order of first appearance, and each case's
    position in the grid; None when the cases are not a full product of them (each combination
    once)."""
    axes = []
    for name in swept:
        values = _column(cases, name)
        axes.append(list(dict.fromkeys(values.tolist())))
    if math.prod(len(axis) for axis in axes) != len(cases):
        return None
    positions = [tuple(axis.index(value) for axis, value in zip(axes, row)) for row in
                 zip(*(_column(cases, name).tolist() for name in swept))]
    if len(set(positions)) != len(cases):
        return None
    return axes, positions


def open_study(path, dims="auto"):
    """The index as an xarray Dataset: dims='auto' gives one dimension per swept field for a
    product study (a zip study, or cases that do not fill the product, get 'case'); dims='case'
    always gives the one dimension 'case'."""
    if dims not in ("auto", "case"):
        raise ValueError(f"dims={dims!r}; allowed: 'auto' or 'case'")
    cases, names, units, swept, attributes = read_index(path)
    others = [name for name in names if name not in swept]
    grid = _grid(cases, swept) if dims == "auto" and attributes.get("combine", "product") == "product" and swept \
        else None
    dataset_attributes = {**attributes, "index_file": str(path)}
    if grid is None:
        coordinates = {dimension_name(name): ("case", _column(cases, name), {"units": units[name], "field": name})
                       for name in swept}
        coordinates["case"] = ("case", cases["case"], {"units": units["case"]})
        variables = {name: ("case", _column(cases, name), {"units": units[name]}) for name in others if name != "case"}
        dataset_attributes["dimensions"] = "case"
        return xr.Dataset(variables, coords=coordinates, attrs=dataset_attributes)
    axes, positions = grid
    shape = tuple(len(axis) for axis in axes)
    dimensions = tuple(dimension_name(name) for name in swept)
    index = tuple(np.array(position) for position in zip(*positions))
    variables = {}
    for name in others:
        values = _column(cases, name)
        if values.dtype == object:
            cells = np.full(shape, "", dtype=object)
        elif values.dtype.kind == "f":
            cells = np.full(shape, np.nan)
        else:
            cells = np.zeros(shape, dtype=values.dtype)
        cells[index] = values
        variables[name] = (dimensions, cells, {"units": units[name]})
    coordinates = {dimension_name(name): (dimension_name(name), np.array(axis, dtype=object if isinstance(axis[0], str)
                                                                          else None),
                                          {"units": units[name], "field": name})
                   for name, axis in zip(swept, axes)}
    dataset_attributes["dimensions"] = " ".join(dimensions)
    return xr.Dataset(variables, coords=coordinates, attrs=dataset_attributes)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    parser.add_argument("index", metavar="INDEX.h5", help="a study's index.h5")
    parser.add_argument("--case-dimension", action="store_true", help="one dimension 'case', even for a product")
    parser.add_argument("--csv", metavar="OUT.csv", help="also write one row per case to OUT.csv")
    args = parser.parse_args(argv)
    try:
        dataset = open_study(args.index, dims="case" if args.case_dimension else "auto")
        if args.csv:
            study_frame(args.index).to_csv(args.csv)
    except StudyIndexError as error:
        print(f"study_table.py: error: {error}", file=sys.stderr)
        return 2
    print(dataset)
    return 0


if __name__ == "__main__":
    sys.exit(main())
