"""Damaged files and grown studies: a flipped byte in a run file's data fails loudly (h5py,
summarize_runs.py); at a study's restart a flipped byte in a case file, or a summary attribute
that its datasets do not give, makes the case run again; a flipped byte in index.h5 is told
from another study and the index rebuilt from the case files; a sweep grown by one value runs
only the new cases, renaming the files whose numbers moved; a changed value of a finished case
or a changed base scene is refused with exit 2 and nothing touched. Which cases ran is read from
the files' inodes and the index's run_count, never from timings."""
import subprocess
import sys

import h5py
import pytest

from conftest import BIN, ROOT, run_eme

BASE = ROOT / "inputs" / "paper_fig4_eme_theta.nml"
STUDY = """&study
  base = '{base}'
  output_dir = '{output}'
/
&sweep field = 'conductivity', values = {values} /
&sweep field = 'scheme', texts = 'eme', 'midpoint' /
&sweep field = 't_end', values = 3.0 /
"""


def study_file(tmp_path, values, name="study", base=BASE):
    path = tmp_path / f"{name}.nml"
    path.write_text(STUDY.format(base=base, output=tmp_path / "out", values=", ".join(map(str, values))))
    return path


def ensemble(study):
    """One rank, no mpirun: the restart logic is rank 0's."""
    return subprocess.run([str(BIN / "eme_ensemble"), str(study)], capture_output=True, text=True, timeout=300,
                          cwd=ROOT)


def flip_data_byte(path, dataset, at=20):
    """Flips one bit inside the (only) chunk of `dataset`'s values."""
    with h5py.File(path, "r") as f:
        chunk = f[dataset].id.get_chunk_info(0)
    data = bytearray(path.read_bytes())
    data[chunk.byte_offset + at] ^= 0x10
    path.write_bytes(bytes(data))


def inodes(directory):
    return {p.name: p.stat().st_ino for p in directory.glob("case_*.h5")}


def index_rows(directory):
    with h5py.File(directory / "index.h5", "r") as f:
        cases = f["cases"][:]
    return [(float(c["conductivity"]), c["scheme"].decode(), c["status"].decode(), int(c["run_count"]))
            for c in cases]


def overrides_by_file(directory):
    result = {}
    for path in sorted(directory.glob("case_*.h5")):
        with h5py.File(path, "r") as f:
            result[path.name] = f.attrs["study_overrides"]
    return result


@pytest.fixture
def finished_study(tmp_path):
    study = study_file(tmp_path, [1.0, 2.0])
    first = ensemble(study)
    assert first.returncode == 0, first.stderr
    return study, tmp_path / "out"


def test_flipped_byte_in_run_data_fails_in_h5py_and_summarize(tmp_path):
    result, path = run_eme(tmp_path, "run", {"integrator": {"scheme": "eme", "dt": 0.15, "t_end": 3.0}})
    assert result.returncode == 0, result.stderr
    with h5py.File(path, "r") as f:
        assert all(f[name].fletcher32 for name in f if f[name].size > 1 and f[name].dtype.kind in "fi")
    flip_data_byte(path, "entropy")
    with h5py.File(path, "r") as f:
        with pytest.raises(OSError, match="Fletcher32"):
            f["entropy"][()]
    summary = subprocess.run([sys.executable, str(ROOT / "postprocess" / "summarize_runs.py"), str(path)],
                             capture_output=True, text=True, timeout=120)
    assert summary.returncode != 0
    assert str(path) in summary.stderr and "min dS" not in summary.stdout


def test_flipped_byte_in_case_file_runs_that_case_again(finished_study):
    study, out = finished_study
    before = inodes(out)
    flip_data_byte(out / "case_00002.h5", "energy")
    again = ensemble(study)
    assert again.returncode == 0, again.stderr
    assert "do not check out" in again.stdout
    assert [row[3] for row in index_rows(out)] == [1, 2, 1, 1]
    after = inodes(out)
    assert after["case_00002.h5"] != before["case_00002.h5"]
    assert {k: v for k, v in after.items() if k != "case_00002.h5"} == \
        {k: v for k, v in before.items() if k != "case_00002.h5"}
    with h5py.File(out / "case_00002.h5", "r") as f:
        f["energy"][()]


def test_summary_attribute_that_its_data_do_not_give_runs_the_case_again(finished_study):
    study, out = finished_study
    with h5py.File(out / "case_00003.h5", "r+") as f:
        figures = f.attrs["run_figures"]
        figures[1] *= 2.0                       # min_entropy_increment
        f.attrs.modify("run_figures", figures)
    again = ensemble(study)
    assert again.returncode == 0, again.stderr
    assert [row[3] for row in index_rows(out)] == [1, 1, 2, 1]


def test_flipped_byte_in_index_is_rebuilt_keeping_every_case(finished_study):
    study, out = finished_study
    before = inodes(out)
    rows = index_rows(out)
    flip_data_byte(out / "index.h5", "cases", at=40)
    again = ensemble(study)
    assert again.returncode == 0, again.stderr
    assert "rebuilt" in again.stdout and "0 to run" in again.stdout
    assert inodes(out) == before
    assert [row[:3] for row in index_rows(out)] == [row[:3] for row in rows]


def test_sweep_grown_by_one_value_runs_only_the_new_cases(finished_study, tmp_path):
    _, out = finished_study
    before = inodes(out)
    old = overrides_by_file(out)
    grown = study_file(tmp_path, [0.5, 1.0, 2.0], name="grown")   # the new value first: numbers move by 2
    again = ensemble(grown)
    assert again.returncode == 0, again.stderr
    assert "2 to run" in again.stdout
    rows = index_rows(out)
    assert [(row[0], row[1]) for row in rows] == [(0.5, "eme"), (0.5, "midpoint"), (1.0, "eme"), (1.0, "midpoint"),
                                                  (2.0, "eme"), (2.0, "midpoint")]
    assert all(row[2] == "complete" and row[3] == 1 for row in rows)
    after = inodes(out)
    # Each finished case's file is the same file (inode) under its new number, its overrides kept.
    for k in range(1, 5):
        assert after[f"case_{k + 2:05d}.h5"] == before[f"case_{k:05d}.h5"]
        assert overrides_by_file(out)[f"case_{k + 2:05d}.h5"] == old[f"case_{k:05d}.h5"]
    assert not list(out.glob("*.moving"))
    # Run once more: nothing runs.
    third = ensemble(grown)
    assert third.returncode == 0 and "0 to run" in third.stdout
    assert inodes(out) == after


def test_changed_value_of_a_finished_case_is_refused(finished_study, tmp_path):
    _, out = finished_study
    before = {p.name: (p.stat().st_ino, p.stat().st_mtime_ns) for p in out.iterdir()}
    changed = study_file(tmp_path, [1.0, 2.5], name="changed")
    result = ensemble(changed)
    assert result.returncode == 2
    assert "index.h5" in result.stderr and "conductivity" in result.stderr and "changed" in result.stderr
    assert {p.name: (p.stat().st_ino, p.stat().st_mtime_ns) for p in out.iterdir()} == before


def test_changed_base_scene_is_refused(tmp_path):
    base = tmp_path / "base.nml"
    base.write_text(BASE.read_text())
    study = study_file(tmp_path, [1.0, 2.0], base=base)
    assert ensemble(study).returncode == 0
    out = tmp_path / "out"
    before = {p.name: (p.stat().st_ino, p.stat().st_mtime_ns) for p in out.iterdir()}
    base.write_text(BASE.read_text().replace("newton_tol = 1.0e-8", "newton_tol = 1.0e-9"))
    assert "1.0e-9" in base.read_text()
    result = ensemble(study)
    assert result.returncode == 2
    assert "base scene" in result.stderr and str(base) in result.stderr
    assert {p.name: (p.stat().st_ino, p.stat().st_mtime_ns) for p in out.iterdir()} == before


def test_progress_counts_complete_and_failed_cases_apart(tmp_path):
    study = tmp_path / "failing.nml"
    study.write_text(f"""&study
  base = '{BASE}'
  output_dir = '{tmp_path / "out"}'
/
&sweep field = 'newton_max_iterations', values = 50, 1 /
&sweep field = 't_end', values = 3.0 /
""")
    result = ensemble(study)
    assert result.returncode == 0, result.stderr
    lines = [line for line in result.stdout.splitlines() if "elapsed" in line]
    assert "1/2 cases complete, 1 failed" in lines[-1]
    # The last line estimates nothing; no line estimates before a case is done ('about 0.0 s left').
    assert lines[-1].endswith(" s elapsed"), lines[-1]
    assert not any(line.startswith("eme_ensemble: 0/") and "left" in line for line in lines), lines
