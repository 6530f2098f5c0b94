"""Fault injection for the tests and the fault campaign (tests/e2e/fault_campaign.py): a small
disk, signals at chosen moments, and a check of what a run left behind.

A small disk is a tmpfs of the given size where `mount` is permitted (root, outside a restricted
container), otherwise the LD_PRELOAD shim tests/e2e/full_disk.c, which makes one directory behave
as a file system of that size without privileges. EME_TEST_FULL_DISK=shim forces the shim."""
import atexit
import contextlib
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import h5py

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent.parent / "postprocess"))
from file_checksums import check_texts  # noqa: E402
_SHIM = {}


def shim_library(name):
    """Compiles the LD_PRELOAD shim tests/e2e/<name>.c once per process; its path."""
    if name not in _SHIM:
        compiler = shutil.which("cc") or shutil.which("gcc")
        if compiler is None:
            raise RuntimeError(f"no C compiler for the shim {name}.c")
        folder = Path(tempfile.mkdtemp(prefix=f"eme_{name}_"))
        atexit.register(shutil.rmtree, folder, True)
        library = folder / f"{name}.so"
        subprocess.run([compiler, "-shared", "-fPIC", "-O2", "-o", str(library), str(HERE / f"{name}.c"), "-ldl"],
                       check=True)
        _SHIM[name] = library
    return _SHIM[name]


def _try_tmpfs(folder, size_bytes):
    if os.environ.get("EME_TEST_FULL_DISK") == "shim" or os.geteuid() != 0 or shutil.which("mount") is None:
        return False
    result = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size_bytes}", "tmpfs", str(folder)],
                            capture_output=True)
    return result.returncode == 0


class SmallDisk:
    """A folder that holds at most `size` bytes; `env` is the environment a process needs to
    see it so (empty for a tmpfs). `resize` gives it another size."""

    def __init__(self, folder, size):
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.tmpfs = _try_tmpfs(self.folder, size)
        self.size = size
        self.env = dict(os.environ)
        if not self.tmpfs:
            self.env.update(LD_PRELOAD=str(shim_library("full_disk")), EME_FULL_DISK_DIR=str(self.folder),
                            EME_FULL_DISK_BYTES=str(size))

    @property
    def method(self):
        return "tmpfs" if self.tmpfs else "LD_PRELOAD shim"

    def resize(self, size):
        self.size = size
        if self.tmpfs:
            subprocess.run(["mount", "-o", f"remount,size={size}", str(self.folder)], check=True)
        else:
            self.env["EME_FULL_DISK_BYTES"] = str(size)

    def close(self):
        if self.tmpfs:
            subprocess.run(["umount", "-l", str(self.folder)], capture_output=True)
            self.tmpfs = False


@contextlib.contextmanager
def small_disk(folder, size):
    disk = SmallDisk(folder, size)
    try:
        yield disk
    finally:
        disk.close()


def mpirun_env_options(env):
    """mpirun -x options that pass the shims' variables on to the ranks."""
    names = [name for name in ("LD_PRELOAD", "EME_FULL_DISK_DIR", "EME_FULL_DISK_BYTES", "EME_KILL_DIR", "EME_KILL_AT",
                               "EME_KILL_MATCH", "EME_KILL_SIGNAL", "EME_KILL_HOLD", "EME_KILL_LOG",
                               "EME_WRITE_EVERY_ROWS") if name in env]
    return [option for name in names for option in ("-x", name)]


def operation_shim(folder, at=None, match=None, signal_number=None, hold=None, log=None, env=None):
    """The environment (os.environ or `env`, plus these) that loads the LD_PRELOAD shim
    kill_at_write.c for the file operations under `folder`: at the `at`-th of them (counting only
    those on a path containing `match`, if given) the process gets `signal_number` (default
    SIGKILL), or, with `hold` (a path), waits there until that file exists (held_process);
    `log` names a file that lists every operation with its path(s)."""
    env = dict(os.environ if env is None else env, LD_PRELOAD=str(shim_library("kill_at_write")),
               EME_KILL_DIR=str(folder))
    for name, value in (("EME_KILL_AT", at), ("EME_KILL_MATCH", match), ("EME_KILL_LOG", log),
                        ("EME_KILL_HOLD", hold)):
        if value is not None:
            env[name] = str(value)
    if signal_number is not None:
        env["EME_KILL_SIGNAL"] = str(int(signal_number))
    return env


def held_process(hold):
    """The id of the process that holds at its chosen file operation (operation_shim's `hold`),
    once it does."""
    held = Path(f"{hold}.held")
    assert wait_for(held.exists), f"no process reached its chosen file operation ({held} is missing)"
    return int(held.read_text())


def process_status(pid):
    """The fields of /proc/PID/status ({} once the process has gone)."""
    try:
        lines = Path(f"/proc/{pid}/status").read_text().splitlines()
    except OSError:
        return {}
    return dict(line.split(":\t", 1) for line in lines if ":\t" in line)


def is_stopped(pid):
    """Whether the process is stopped by a signal (SIGSTOP: state T)."""
    return process_status(pid).get("State", "").startswith("T")


def _in_mask(mask, number):
    return bool(int(mask or "0", 16) >> (int(number) - 1) & 1)


def signal_caught(pid, number):
    """Whether the process has a handler for signal `number` (a shell's trap is set)."""
    return _in_mask(process_status(pid).get("SigCgt"), number)


def processes_naming(text):
    """The ids of the processes whose command line contains `text` (Linux /proc; no procps needed)."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            command = (entry / "cmdline").read_bytes()
        except OSError:        # the process has ended meanwhile
            continue
        if text.encode() in command:
            found.append(int(entry.name))
    return found


def check_run_file(path):
    """What a reader finds in a run file: (status, steps_completed). Raises if the file cannot
    be read, lacks its status, a text fails the file's text_checksum (docs/output.md), or a
    dataset's length disagrees with the step rows (step_rows, or steps_completed in older files:
    per-point datasets rows + 1, per-step datasets rows)."""
    with h5py.File(path, "r") as f:
        check_texts(f, path)
        status = f.attrs["status"]
        steps = int(f.attrs["steps_completed"])
        step_rows = int(f.attrs.get("step_rows", steps))
        for name, dataset in f.items():
            dataset[()]                      # every value can be read
            if "rows" not in dataset.attrs:  # the columns' dimension scales
                continue
            rows = dataset.attrs["rows"]
            expected = step_rows + 1 if rows == "point" else step_rows
            if dataset.shape[0] != expected:
                raise AssertionError(f"{path}: /{name} has {dataset.shape[0]} rows, step_rows = {step_rows}")
    return status, steps


def wait_for(predicate, timeout=120.0, interval=0.02):
    """Polls until predicate() is true; False on timeout."""
    deadline = time.time() + timeout
    while time.time() < deadline:
        if predicate():
            return True
        time.sleep(interval)
    return False


def signal_after(command, delay, number, env=None, cwd=None, start_marker=None):
    """Starts `command`, waits until `start_marker` exists (if given) and then `delay` seconds,
    sends signal `number`, and returns the completed process's (return code, stdout, stderr)."""
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, cwd=cwd)
    if start_marker is not None:
        wait_for(lambda: Path(start_marker).exists() or process.poll() is not None)
    time.sleep(delay)
    if process.poll() is None:
        process.send_signal(number)
    out, err = process.communicate(timeout=300)
    return process.returncode, out, err


SIGNALS = {"SIGTERM": signal.SIGTERM, "SIGINT": signal.SIGINT, "SIGKILL": signal.SIGKILL}
