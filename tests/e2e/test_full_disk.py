"""A full disk (a small tmpfs, or the LD_PRELOAD shim where mounting is not permitted; see
faults.py): eme_run exits 1 with the OS's reason, the file and the input file, never crashes,
never calls a file complete that is not, and keeps the steps written before; a study stops
cleanly, keeps a readable index and finishes when run again with room."""
import re
import subprocess

import h5py
import numpy as np
import pytest

from conftest import BIN, ROOT, namelist_text, read_run
from faults import check_run_file, mpirun_env_options, small_disk

PAPER_FILE_BYTES = 49_296        # the paper scene's file, 134 steps (measured)
LONG_RUN = {"dt": 0.01, "t_end": 1000.0}  # 100000 steps, about 25 MB


def run_on(disk, tmp_path, name, integrator):
    output = disk.folder / f"{name}.h5"
    namelist = tmp_path / f"{name}.nml"
    namelist.write_text(namelist_text({"integrator": integrator, "output": {"file": str(output)}}))
    result = subprocess.run([str(BIN / "eme_run"), str(namelist)], capture_output=True, text=True, env=disk.env,
                            timeout=300)
    return result, output, namelist


def assert_reported(result, output, namelist):
    assert result.returncode == 1, (result.returncode, result.stderr)
    assert "No space left on device" in result.stderr
    assert f"{output}.part" in result.stderr and str(namelist) in result.stderr
    assert not output.exists()


@pytest.mark.parametrize("size", [4096, 16384, 40960])
def test_a_short_run_on_a_full_disk(tmp_path, eme_run_binary, size):
    """The paper scene writes its whole file when it ends: no room, no file, a clear message."""
    with small_disk(tmp_path / "disk", size) as disk:
        result, output, namelist = run_on(disk, tmp_path, "paper", {"t_end": 20.0})
        assert_reported(result, output, namelist)
        assert "nothing was kept" in result.stderr
        assert not list(disk.folder.iterdir()), disk.method


@pytest.mark.parametrize("size", [6_000_000, 10_000_000, 15_000_000])
def test_a_long_run_on_a_full_disk_keeps_its_written_steps(tmp_path, eme_run_binary, size):
    """A long run writes a window of rows at a time; when the disk is full, the file keeps
    every row of its last window, says why, and its datasets agree in length."""
    with small_disk(tmp_path / "disk", size) as disk:
        result, output, namelist = run_on(disk, tmp_path, "long", LONG_RUN)
        assert_reported(result, output, namelist)
        kept = int(re.search(r"keeps the (\d+) steps written before", result.stderr).group(1))
        status, steps = check_run_file(f"{output}.part")
        assert status == "incomplete: cannot write the output file: No space left on device", disk.method
        assert steps == kept > 1000         # one window or more (1 s or 4 MiB of rows each)
        run = read_run(f"{output}.part")
        assert run["attrs"]["failure_kind"] == "io"
        np.testing.assert_allclose(run["time"], 0.01 * np.arange(steps + 1))
        energy = run["energy"]
        assert np.max(np.abs(energy - energy[0])) <= 1e-10 * abs(energy[0])


def test_a_run_that_fits_is_complete(tmp_path, eme_run_binary):
    """The same mechanism with room to spare: complete, renamed, nothing left over."""
    with small_disk(tmp_path / "disk", 4 * PAPER_FILE_BYTES) as disk:
        result, output, _ = run_on(disk, tmp_path, "paper", {"t_end": 20.0})
        assert result.returncode == 0, result.stderr
        assert check_run_file(output) == ("complete", 134)
        assert sorted(p.name for p in disk.folder.iterdir()) == ["paper.h5"]


STUDY = """&study base = '{base}', output_dir = '{output}' /
&sweep field = 'theta(2)', values = 340, 341, 342, 343, 344, 345, 346, 347 /
"""


def results_recorded(output):
    """{case: (status, failure_kind)} from index.h5 with index.journal's lines over it."""
    with h5py.File(output / "index.h5", "r") as f:
        cases = f["cases"][:]
    recorded = {int(row["case"]): (row["status"].decode(), row["failure_kind"].decode()) for row in cases}
    journal = output / "index.journal"
    if journal.exists():
        for line in journal.read_text().splitlines()[1:]:
            fields = line.split("\t")
            recorded[int(fields[0])] = (fields[-2], fields[1])
    return recorded


def test_a_study_on_a_full_disk_stops_and_resumes(tmp_path, eme_run_binary):
    """Eight paper-scene cases with room for about four: the study stops at the first case it
    cannot write (every later one would fail the same way), exit 1, with a readable index that
    records what is done; run again with room, it runs only the rest."""
    with small_disk(tmp_path / "disk", 6 * PAPER_FILE_BYTES) as disk:
        output = disk.folder / "study"
        study = tmp_path / "study.nml"
        study.write_text(STUDY.format(base=ROOT / "inputs" / "paper_fig4_eme_theta.nml", output=output))
        command = ["mpirun", "--allow-run-as-root", "--oversubscribe", *mpirun_env_options(disk.env), "-n", "2",
                   str(BIN / "eme_ensemble"), str(study)]
        result = subprocess.run(command, capture_output=True, text=True, env=disk.env, cwd=ROOT, timeout=300)
        assert result.returncode == 1, result.stdout + result.stderr
        assert "No space left on device" in result.stderr + result.stdout
        # The results are in index.h5, and in index.journal beside it if the last index.h5 found
        # no room (the study then says so).
        recorded = results_recorded(output)
        if (output / "index.journal").exists():
            assert "index.journal holds every result" in result.stdout
        done = [c for c, (status, _) in recorded.items() if status == "complete"]
        assert 1 <= len(done) < 8, result.stdout + result.stderr
        assert done == [c for c in range(1, 9) if (output / f"case_{c:05d}.h5").exists()]
        for c in done:
            assert check_run_file(output / f"case_{c:05d}.h5")[0] == "complete"
        assert any(kind == "io" and status.startswith("failed: cannot write") for status, kind in recorded.values())
        disk.resize(40 * PAPER_FILE_BYTES)
        result = subprocess.run(command, capture_output=True, text=True, env=disk.env, cwd=ROOT, timeout=300)
        assert result.returncode == 0, result.stdout + result.stderr
        assert f"{8 - len(done)} to run ({len(done)} complete from an earlier run)" in result.stdout
        with h5py.File(output / "index.h5", "r") as f:
            cases = f["cases"][:]
        assert all(status == b"complete" for status in cases["status"])
        assert [row["run_count"] for row in cases if row["case"] in done] == [1] * len(done)


def chain_on_disk(disk, tmp_path, name):
    """The rod of inputs/chain_rod_heat.nml cut into 5000 springs, 100 steps of 0.1 ms with a
    snapshot at every step (160 kB each), writing into the small disk."""
    output = disk.folder / f"{name}.h5"
    text = (ROOT / "inputs" / "chain_rod_heat.nml").read_text()
    changes = {"links = 100": "links = 5000", "50*340.0, 50*280.0": "2500*340.0, 2500*280.0", "dt = 0.01": "dt = 1.0e-4",
               "t_end = 2.0": "t_end = 0.01", "snapshot_every = 5": "snapshot_every = 1",
               "'results/chain_rod_heat.h5'": f"'{output}'"}
    for old, new in changes.items():
        assert old in text, old
        text = text.replace(old, new)
    namelist = tmp_path / f"{name}.nml"
    namelist.write_text(text)
    return output, namelist


def run_chain(disk, namelist, ranks, *options):
    command = ["mpirun", "--allow-run-as-root", "--oversubscribe", *mpirun_env_options(disk.env), "-n", str(ranks),
               str(BIN / "eme_run"), str(namelist), *options]
    return subprocess.run(command, capture_output=True, text=True, env=disk.env, timeout=240)


@pytest.mark.parametrize("ranks", [1, 2])
@pytest.mark.parametrize("size", [3_000_000, 16_000_000])
def test_a_chain_whose_snapshots_fill_the_disk_stops_cleanly_and_continues(tmp_path, eme_run_binary, ranks, size):
    """A split run whose snapshot finds the disk full: every rank stops (on 2 ranks the one that
    met the full disk had left the other in HDF5's next collective call: a hang; on 1 rank HDF5
    crashed at exit after its failed close, exit 139), exit 1 naming the OS's reason and the
    steps kept, FILE.part marked `failure_kind io` with a snapshot for every row it keeps (none
    at 3 MB, where the first snapshot does not fit; most at 16 MB), and `-eme_continue` with
    room finishes the run."""
    with small_disk(tmp_path / "disk", size) as disk:
        output, namelist = chain_on_disk(disk, tmp_path, "rod")
        result = run_chain(disk, namelist, ranks)
        assert result.returncode == 1, (result.returncode, result.stderr[-2000:])
        assert "No space left on device" in result.stderr, disk.method
        kept = int(re.search(r"keeps the (\d+) steps written before", result.stderr).group(1))
        part = f"{output}.part"
        with h5py.File(part, "r") as f:
            assert f.attrs["status"].startswith("incomplete: cannot write the output file")
            assert f.attrs["failure_kind"] == "io" and int(f.attrs["steps_completed"]) == kept
            assert f["time"].shape == (kept + 1,)
            snapshots = f["snapshots/time"][()] if "snapshots" in f else np.zeros(0)
        if kept > 0:
            assert len(snapshots) == kept + 1      # snapshot_every = 1: t = 0 and every step kept
        else:
            assert len(snapshots) <= 1
        if size > 10_000_000:
            assert kept > 10, result.stderr
        disk.resize(200_000_000)
        if kept > 0:
            result = run_chain(disk, namelist, ranks, "-eme_continue")
            assert result.returncode == 0, result.stderr[-2000:]
            with h5py.File(output, "r") as f:
                assert f.attrs["status"] == "complete" and f["snapshots/time"].shape == (101,)
