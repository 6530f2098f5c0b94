"""`make figures` from a clean clone: every figure is drawn after the runs it shows, which make
runs from their inputs (results/NAME.h5 from inputs/NAME.nml), and after the Python set-up.
Checked with `make -n` (what make would do) in a fresh clone of this repository's last commit,
so that no build is needed; docs/figures.md, gives the real run's numbers."""
import re
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
FIGURE_INPUTS = {
    "fig3_snapshots": ["paper_fig3"],
    "fig4_eme": [f"paper_fig4_eme_{v}" for v in ("entropy", "theta", "internal_energy")],
    "fig4_eme_vs_midpoint": [f"paper_fig4_{s}_{v}" for s in ("eme", "midpoint")
                             for v in ("entropy", "theta", "internal_energy")],
    "fig5_constrained": [f"paper_fig5_{c}" for c in ("fixed_length", "fixed_temperature", "both")],
    "temperatures_jz": [f"paper_fig4_{s}_{v}" for s in ("eme", "midpoint")
                        for v in ("entropy", "theta", "internal_energy")],
}


@pytest.fixture(scope="module")
def planned(tmp_path_factory):
    """The commands `make -n figures` lists in a fresh clone, one per line."""
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("needs git and a git checkout")
    clone = tmp_path_factory.mktemp("clone") / "repository"
    subprocess.run(["git", "clone", "--quiet", str(ROOT), str(clone)], check=True, timeout=120)
    result = subprocess.run(["make", "-n", "figures"], cwd=clone, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    return result.stdout.splitlines()


def first_line(lines, pattern):
    return next((i for i, line in enumerate(lines) if re.search(pattern, line)), None)


def test_each_figure_is_drawn_after_the_runs_it_shows(planned):
    linked = first_line(planned, r"-o build/bin/eme_run ")
    venv = first_line(planned, r"pip install .* -r postprocess/requirements\.txt")
    assert linked is not None and venv is not None
    for figure, inputs in FIGURE_INPUTS.items():
        drawn = first_line(planned, rf"\.venv/bin/python postprocess/\S+\.py .* -o results/figures/{figure}$")
        assert drawn is not None, f"make figures does not draw {figure}"
        assert venv < drawn
        for name in inputs:
            ran = first_line(planned, rf"^build/bin/eme_run inputs/{name}\.nml ")
            assert ran is not None and linked < ran < drawn, (figure, name)
            assert f"results/{name}.h5" in planned[drawn]
    assert not any("run 'make run' first" in line for line in planned)


def test_fig3_is_drawn_at_the_paper_times_from_a_24_s_run(planned):
    drawn = planned[first_line(planned, r"plot_snapshots\.py")]
    assert "--times 0 8 16 24" in drawn
    text = (ROOT / "inputs" / "paper_fig3.nml").read_text()
    assert re.search(r"t_end\s*=\s*24\.0", text) and "results/paper_fig3.h5" in text
