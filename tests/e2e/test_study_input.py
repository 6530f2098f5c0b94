"""Study input that must be refused before anything is written: sweeps whose cases would
collide (two sweeps of one field, of overlapping elements, of a field and its old name, of the
output file), files without groups, a repeated &study, NaN in a sweep; a refused study leaves
an earlier index exactly as it was. Sweeps of different elements of one array still run."""
import subprocess

import h5py
import pytest

from conftest import BIN, ROOT


def study_text(base, output, sweeps):
    return f"&study base = '{base}', output_dir = '{output}' /\n" + "".join(f"&sweep {s} /\n" for s in sweeps)


@pytest.fixture
def base(tmp_path):
    path = tmp_path / "base.nml"
    path.write_text("&integrator t_end = 0.3 /\n")
    return path


def ensemble(study):
    return subprocess.run([str(BIN / "eme_ensemble"), str(study)], capture_output=True, text=True, timeout=120, cwd=ROOT)


COLLISIONS = {
    "one field twice": (["field = 'dt', values = 0.1, 0.2", "field = 'dt', values = 0.05"],
                        ["&sweep 'dt' and &sweep 'dt' set the same value"]),
    "whole array and an element": (["field = 'theta', values = 300, 300", "field = 'theta(2)', values = 310"],
                                   ["&sweep 'theta' and &sweep 'theta(2)'"]),
    "overlapping ranges": (["field = 'p2(1:2)', values = 0.5, 0.5", "field = 'p2(2:3)', values = 0.1, 0.1"],
                           ["&sweep 'p2(1:2)' and &sweep 'p2(2:3)'"]),
    "a field and its old name": (["field = 'tolerance', values = 1e-6", "field = 'ts_tolerance', values = 1e-7"],
                                 ["&sweep 'tolerance' and &sweep 'ts_tolerance' set the same value"]),
    "upper case twice": (["field = 'DT', values = 0.1", "field = 'dt', values = 0.2"], ["set the same value"]),
    "the output file": (["field = 'file', texts = 'a.h5', 'b.h5'"],
                        ["&sweep 'file'", "output_dir/case_NNNNN.h5", "allowed: any eme_run field but &output file"]),
    "NaN in values": (["field = 'dt', values = 0.1, nan"], ["&sweep", "'values'", "NaN and Inf are not allowed"]),
    "a subscript past the end": (["field = 'theta(3)', values = 300"],
                                 ["&sweep 'theta(3)'", "theta(3): subscript (3) is out of range", "case 1"]),
}


@pytest.mark.parametrize("case", sorted(COLLISIONS))
def test_colliding_or_bad_sweeps_are_refused_before_anything_is_written(tmp_path, base, eme_run_binary, case):
    sweeps, words = COLLISIONS[case]
    output = tmp_path / "out"
    study = tmp_path / "study.nml"
    study.write_text(study_text(base, output, sweeps))
    result = ensemble(study)
    assert result.returncode == 2, result.stdout + result.stderr
    assert result.stderr.startswith(f"eme_ensemble: {study}: "), result.stderr
    for word in words:
        assert word in result.stderr, result.stderr
    assert not output.exists()


@pytest.mark.parametrize("text,words", [
    ("", ["no namelist group found", "allowed groups: &study, &sweep"]),
    ("! only a comment\n", ["no namelist group found"]),
    ("study base = 'x.nml' /\n", ["text outside any namelist group"]),
    ("&study base = 'x.nml' /\n&study combine = 'zip' /\n", ["&study appears 2 times"]),
    ("&study base = 'x.nml'\n&sweep field = 'dt' values = 0.1 /\n", ["&study is not closed by '/' before '&sweep"]),
])
def test_bad_study_files(tmp_path, eme_run_binary, text, words):
    study = tmp_path / f"bad_{tmp_path.name}.nml"     # its default output_dir, results/<name>, is unused
    study.write_text(text)
    result = ensemble(study)
    assert result.returncode == 2
    for word in words + [str(study)]:
        assert word in result.stderr, result.stderr
    assert [p.name for p in tmp_path.iterdir()] == [study.name]
    assert not (ROOT / "results" / study.stem).exists()


def test_a_refused_study_leaves_the_earlier_index_as_it_was(tmp_path, base, eme_run_binary):
    output = tmp_path / "out"
    study = tmp_path / "study.nml"
    study.write_text(study_text(base, output, ["field = 'dt', values = 0.1, 0.15"]))
    first = ensemble(study)
    assert first.returncode == 0, first.stderr
    files = {p: p.read_bytes() for p in sorted(output.iterdir())}
    assert output / "index.h5" in files and len(files) == 3
    study.write_text(study_text(base, output, ["field = 'dt', values = 0.1, 0.15", "field = 'dt', values = 0.2"]))
    second = ensemble(study)
    assert second.returncode == 2 and "set the same value" in second.stderr
    assert {p: p.read_bytes() for p in sorted(output.iterdir())} == files


def test_different_elements_of_one_array_may_be_swept(tmp_path, base, eme_run_binary):
    output = tmp_path / "out"
    study = tmp_path / "study.nml"
    study.write_text(study_text(base, output, ["field = 'theta(1)', values = 290, 300",
                                               "field = 'theta(2)', values = 340"]))
    result = ensemble(study)
    assert result.returncode == 0, result.stderr
    with h5py.File(output / "case_00002.h5", "r") as f:
        assert list(f.attrs["theta"]) == [300.0, 340.0]


@pytest.mark.parametrize("repeats", [5000000, 1001, 0])
def test_repeats_beyond_its_bound_are_refused_not_a_crash(tmp_path, base, eme_run_binary, repeats):
    """repeats = 5000000 sized an array on the stack and ended in SIGSEGV with index files left."""
    output = tmp_path / "out"
    study = tmp_path / "study.nml"
    study.write_text(f"&study base = '{base}', output_dir = '{output}', repeats = {repeats} /\n"
                     "&sweep field = 'dt', values = 0.1 /\n")
    result = ensemble(study)
    assert result.returncode == 2, result.stderr
    assert f"&study: repeats = {repeats} is not allowed; allowed: an integer from 1 to 1000" in result.stderr
    assert not output.exists()
