"""The README's examples run as written (issue: a user copies them right after `make run`).

The commands of the README's "One run" section are taken from the README itself and run in a
scratch copy of the project's layout (build and .venv linked, inputs and postprocess copied), so
that they do not touch this checkout's results, after the paper scene's run that `make run`
makes there; each must exit 0.
The input shown must be the input file's, and the output shown must be what the command prints
(its numbers and status; the wall times vary)."""
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SECTION = re.compile(r"^## One run\n(.*?)^## ", re.MULTILINE | re.DOTALL)
BLOCK = re.compile(r"^```(\w*)\n(.*?)^```", re.MULTILINE | re.DOTALL)


def readme_blocks():
    """[(language, text)] of the code blocks of the README's "One run" section, in order."""
    section = SECTION.search((ROOT / "README.md").read_text()).group(1)
    return BLOCK.findall(section)


@pytest.fixture(scope="module")
def workspace(tmp_path_factory, eme_run_binary):
    """A directory laid out as the checkout, with results/ as `make run` leaves the example's file."""
    place = tmp_path_factory.mktemp("readme")
    for name in ("build", ".venv"):
        (place / name).symlink_to(ROOT / name)
    for name in ("inputs", "postprocess"):
        shutil.copytree(ROOT / name, place / name)
    (place / "results").mkdir()
    made = run_shell("build/bin/eme_run inputs/paper_fig4_eme_theta.nml", place)
    assert made.returncode == 0 and (place / "results" / "paper_fig4_eme_theta.h5").exists(), made.stderr
    return place


def run_shell(line, cwd):
    return subprocess.run(["bash", "-c", line], cwd=cwd, capture_output=True, text=True, timeout=300)


def test_the_commands_run_as_written_and_print_what_the_readme_shows(workspace):
    blocks = readme_blocks()
    commands = [line for language, text in blocks if language == "sh" for line in text.splitlines()
                if line.strip() and not line.startswith("#")]
    assert len(commands) == 3, commands
    outputs = []
    for command in commands:
        result = run_shell(command, workspace)
        assert result.returncode == 0, (command, result.stdout, result.stderr)
        outputs.append(result.stdout)
    shown = [text for language, text in blocks if language == ""][0].splitlines()
    printed = (outputs[0] + outputs[1]).splitlines()
    without_times = lambda line: re.sub(r"\s+\d+\.\d+ s$|\s+\d+\.\d{3}\s+complete$", "", line)
    assert [without_times(line) for line in printed] == [without_times(line) for line in shown]
    assert (workspace / "results" / "study_dt_sweep" / "index.h5").exists()


def test_the_input_shown_is_the_input_file(workspace):
    shown = [text for language, text in readme_blocks() if language == "fortran"][0]
    lines = [line for line in (ROOT / "inputs" / "paper_fig4_eme_theta.nml").read_text().splitlines()
             if not line.startswith("!")]
    assert shown.splitlines() == lines


def test_the_python_example_runs(workspace):
    code = [text for language, text in readme_blocks() if language == "python"][0]
    result = subprocess.run([sys.executable, "-c", code], cwd=workspace, capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    shown = [text for language, text in readme_blocks() if language == ""][1]
    assert result.stdout == shown
