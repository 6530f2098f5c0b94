"""Snapshots of a state split over MPI ranks, written with parallel HDF5 (src/io/hdf5_snapshots.f90,
src/io/hdf5_snapshot_storage.c, the group's layout src/io/hdf5_snapshot_layout.c; docs/output.md,
Snapshots). build/tests/snapshot_probe writes snapshots of known values from every rank, each rank
its own masses and springs; the expected values here are the probe's formulas typed again
(tests/e2e/snapshot_probe.f90), the shapes, units and axes those of docs/output.md."""
import os
import shutil
import subprocess
import sys

import h5py
import numpy as np
import pytest

from conftest import BIN, ROOT, namelist_text

sys.path.insert(0, str(ROOT / "postprocess"))

import file_checksums  # noqa: E402

PROBE = BIN.parent / "tests" / "snapshot_probe"
UNITS = {"time": "s", "q": "m", "p": "N s", "gamma": "m", "theta": "K", "entropy": "J/K",
         "internal_energy": "J", "mass": "1", "spring": "1", "component": "1"}
AXES = {"time": ["time"], "q": ["time", "mass", "component"], "p": ["time", "mass", "component"],
        "gamma": ["time", "spring"], "theta": ["time", "spring"], "entropy": ["time", "spring"],
        "internal_energy": ["time", "spring"]}
CHUNK_VALUES = 32768          # numbers in one chunk of a snapshot at most (256 KiB), docs/output.md


def chunk_length(length, width):
    """docs/output.md: an axis of `length` entries of `width` numbers split evenly into the fewest
    chunks of at most CHUNK_VALUES numbers."""
    chunks = -(-length * width // CHUNK_VALUES)
    return -(-length // chunks)


def empty_file(path):
    """An HDF5 file in the format of the project's run files (HDF5 1.8's)."""
    h5py.File(path, "w", libver=("v108", "v108")).close()
    return path


def probe(ranks, path, **arguments):
    """Runs snapshot_probe on `ranks` MPI ranks with name=value arguments."""
    command = ["mpirun", "--allow-run-as-root", "--oversubscribe", "-n", str(ranks), str(PROBE), f"file={path}",
               *(f"{name}={value}" for name, value in arguments.items())]
    return subprocess.run(command, capture_output=True, text=True, timeout=300)


def expected(snapshots, masses, springs, dimension, first=0):
    """The probe's values, from its formulas: snapshot k, mass i, component c, spring a (1-based)."""
    k = np.arange(first, first + snapshots, dtype=float)
    i = np.arange(1, masses + 1, dtype=float)
    c = np.arange(1, dimension + 1, dtype=float)
    a = np.arange(1, springs + 1, dtype=float)
    q = i[None, :, None] + 0.1 * c[None, None, :] + 1000.0 * k[:, None, None]
    return {"time": 0.5 * k + 0.125, "q": q, "p": -q,
            "gamma": -(a[None, :] + 0.5) - 1000.0 * k[:, None],
            "theta": 300.0 + a[None, :] + 1000.0 * k[:, None],
            "tau": 0.25 * a[None, :] + 7.0 + 1000.0 * k[:, None]}


def text(value):
    return value.decode() if isinstance(value, bytes) else str(value)


def every_dataset(group):
    found = {}
    group.visititems(lambda name, item: found.setdefault(name, item) if isinstance(item, h5py.Dataset) else None)
    return found


@pytest.mark.parametrize("ranks, masses, mass_split, spring_split", [
    (1, 11, "11", "12"),
    (2, 11, "3,8", "7,5"),               # uneven, and the springs split unlike the masses
    (3, 11, "4,0,7", "0,5,7"),           # a rank without masses, one without springs
])
def test_snapshots_of_known_values_from_uneven_splits(tmp_path, ranks, masses, mass_split, spring_split):
    path = empty_file(tmp_path / "run.h5")
    springs = masses + 1                  # a 'fixed-fixed' chain: N + 1 springs
    result = probe(ranks, path, masses=masses, springs=springs, dimension=3, snapshots=3, mass_split=mass_split,
                   spring_split=spring_split)
    assert result.returncode == 0, result.stderr
    want = expected(3, masses, springs, 3)
    with h5py.File(path, "r") as f:
        group = f["snapshots"]
        for name in ("time", "q", "p", "gamma", "theta"):
            assert group[name].shape == want[name].shape, name
            np.testing.assert_array_equal(group[name][()], want[name], err_msg=name)
        np.testing.assert_array_equal(group["entropy"][()], want["tau"])
        assert "internal_energy" not in group
        for name, dataset in every_dataset(group).items():
            assert dataset.fletcher32, f"{name} has no Fletcher-32 checksum"
            assert text(dataset.attrs["units"]) == UNITS[name], name
            assert text(dataset.attrs["description"]), name
            if name in AXES:
                assert [text(axis) for axis in dataset.attrs["dims"]] == AXES[name], name
                scales = [[scale.name for scale in dataset.dims[d].values()] for d in range(dataset.ndim)]
                assert scales == [[f"/snapshots/{axis}"] for axis in AXES[name]], name
        np.testing.assert_array_equal(group["mass"][()], np.arange(1, masses + 1))
        np.testing.assert_array_equal(group["spring"][()], np.arange(1, springs + 1))
        assert [text(c) for c in group["component"][()]] == ["x", "y", "z"]
        assert group["q"].chunks == (1, masses, 3)


def test_one_and_two_ranks_write_the_same_data_across_chunks(tmp_path):
    """N = 25,000 in 3 components: chunks of 8,334 masses, so that the ranks' parts straddle
    chunks (one rank's part ends inside a chunk, and with 3 ranks one rank holds a single mass)."""
    masses, springs = 25_000, 25_001
    files = {}
    for ranks, mass_split, spring_split in ((1, "25000", "25001"), (2, "12500,12500", "12000,13001"),
                                            (3, "8333,1,16666", "1,25000,0")):
        files[ranks] = empty_file(tmp_path / f"ranks{ranks}.h5")
        result = probe(ranks, files[ranks], masses=masses, springs=springs, dimension=3, snapshots=2,
                       mass_split=mass_split, spring_split=spring_split, tau="internal_energy")
        assert result.returncode == 0, result.stderr
    want = expected(2, masses, springs, 3)
    with h5py.File(files[1], "r") as one:
        assert one["snapshots/q"].chunks == (1, chunk_length(masses, 3), 3) == (1, 8334, 3)
        assert one["snapshots/gamma"].chunks == (1, chunk_length(springs, 1)) == (1, 25001)
        np.testing.assert_array_equal(one["snapshots/q"][()], want["q"])
        np.testing.assert_array_equal(one["snapshots/internal_energy"][()], want["tau"])
        for ranks in (2, 3):
            with h5py.File(files[ranks], "r") as other:
                assert sorted(every_dataset(other["snapshots"])) == sorted(every_dataset(one["snapshots"]))
                for name, dataset in every_dataset(one["snapshots"]).items():
                    np.testing.assert_array_equal(other["snapshots"][name][()], dataset[()],
                                                  err_msg=f"{name} on {ranks} ranks")


def test_later_calls_append_with_another_rank_count_and_the_datasets_asked_for(tmp_path):
    """Without gamma and theta, tau being theta: only time, q and p; a later call on another
    number of ranks appends to them."""
    path = empty_file(tmp_path / "run.h5")
    result = probe(2, path, masses=5, springs=5, dimension=2, snapshots=2, gamma="no", theta="no", tau="none")
    assert result.returncode == 0, result.stderr
    result = probe(1, path, masses=5, springs=5, dimension=2, snapshots=1, first=2, gamma="no", theta="no",
                   tau="none")
    assert result.returncode == 0, result.stderr
    want = expected(3, 5, 5, 2)
    with h5py.File(path, "r") as f:
        assert sorted(f["snapshots"]) == ["component", "mass", "p", "q", "time"]
        np.testing.assert_array_equal(f["snapshots/q"][()], want["q"])
        np.testing.assert_array_equal(f["snapshots/time"][()], want["time"])
        assert [text(c) for c in f["snapshots/component"][()]] == ["x", "y"]


def read_back(path):
    with h5py.File(path, "r") as f:
        return {name: dataset[()] for name, dataset in every_dataset(f).items()}


def refused(result, *words):
    """The probe failed with one message on standard error holding `words`."""
    assert result.returncode == 1, result.stdout + result.stderr
    message = [line for line in result.stderr.splitlines() if line.startswith("snapshot_probe: ")]
    assert len(message) == 1, result.stderr
    for word in words:
        assert word in message[0], message[0]
    return message[0]


@pytest.mark.parametrize("change, words", [
    ({"masses": 6}, ["/snapshots/q", "(5, 3)", "(6, 3)"]),
    ({"dimension": 2}, ["/snapshots/q", "(5, 3)", "(5, 2)"]),
    ({"springs": 4}, ["/snapshots/gamma", "(5)", "(4)"]),
    ({"tau": "internal_energy"}, ["/snapshots/internal_energy", "not in the file"]),
    ({"gamma": "no"}, ["/snapshots/gamma", "this snapshot has no gamma"]),
    ({"mass_split": "2,2"}, ["4 masses in all", "has 5"]),
    ({"mass_split": "6,-1"}, ["rank 1's arrays do not fit"]),
])
def test_a_snapshot_that_does_not_fit_the_file_is_refused_and_the_file_kept(tmp_path, change, words):
    path = empty_file(tmp_path / "run.h5")
    assert probe(2, path, masses=5, springs=5, dimension=3, snapshots=2).returncode == 0
    before = read_back(path)
    arguments = {"masses": 5, "springs": 5, "dimension": 3, "snapshots": 1, "first": 2, **change}
    refused(probe(2, path, **arguments), str(path), *words)
    after = read_back(path)
    assert sorted(after) == sorted(before)
    for name in before:
        np.testing.assert_array_equal(after[name], before[name], err_msg=name)


def test_a_bad_path_is_refused_with_the_reason(tmp_path):
    missing = tmp_path / "no_folder" / "run.h5"
    refused(probe(2, missing, masses=4), str(missing), "No such file or directory")
    assert not missing.parent.exists()
    refused(probe(1, tmp_path, masses=4), str(tmp_path), "not a regular file")
    other = tmp_path / "notes.h5"
    other.write_text("not HDF5\n")
    refused(probe(2, other, masses=4), str(other), "HDF5")
    assert other.read_text() == "not HDF5\n"


def test_a_file_without_write_permission_is_refused(tmp_path):
    """As root, permission bits bind only without the capability to override them: the probe runs
    with CAP_DAC_OVERRIDE and CAP_DAC_READ_SEARCH dropped (setpriv)."""
    path = empty_file(tmp_path / "run.h5")
    path.chmod(0o444)
    prefix = []
    if os.geteuid() == 0:
        if shutil.which("setpriv") is None:
            pytest.skip("running as root without setpriv: permission bits do not bind")
        drop = "-dac_override,-dac_read_search"
        prefix = ["setpriv", "--bounding-set", drop, "--inh-caps", drop]
    command = [*prefix, "mpirun", "--allow-run-as-root", "-n", "2", str(PROBE), f"file={path}", "masses=4"]
    result = subprocess.run(command, capture_output=True, text=True, timeout=600)
    refused(result, str(path), "Permission denied")
    with h5py.File(path, "r") as f:
        assert "snapshots" not in f


def test_snapshots_keep_a_run_files_texts_checksum(tmp_path):
    """The snapshots' texts are fixed-length (under the object headers' checksums), so that a run
    file's text_checksum, which this writer does not hold, stays right: summarize_runs.py reads the
    file after snapshots were appended."""
    (tmp_path / "one.nml").write_text(namelist_text({"integrator": {"scheme": "eme", "dt": 0.15, "t_end": 0.15},
                                                     "output": {"file": "one.h5"}}))
    run = subprocess.run([str(BIN / "eme_run"), "one.nml"], cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr
    path = tmp_path / "one.h5"
    result = probe(2, path, masses=7, springs=7, dimension=3, snapshots=2)
    assert result.returncode == 0, result.stderr
    with h5py.File(path, "r") as f:
        assert "text_checksum" in f.attrs
        file_checksums.check_texts(f, path)
        assert f["snapshots/q"].shape == (2, 7, 3)
    summary = subprocess.run([sys.executable, str(ROOT / "postprocess" / "summarize_runs.py"), str(path)],
                             capture_output=True, text=True, timeout=300)
    assert summary.returncode == 0, summary.stderr
