"""make docs redraws the module graph; with no source change the redrawn files are the same
bytes, so a second make docs leaves `git status` clean (the SVG had a date and random clip-path
ids in it). Each drawing runs in a process of its own, as make docs runs it (its own hash seed)."""
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def draw(output, seed):
    environment = {**os.environ, "PYTHONHASHSEED": str(seed)}
    result = subprocess.run([sys.executable, str(ROOT / "tests" / "architecture" / "module_graph.py"), "-o",
                             str(output)], capture_output=True, text=True, timeout=600, env=environment)
    assert result.returncode == 0, result.stderr


def test_two_drawings_of_the_same_sources_are_the_same_bytes(tmp_path):
    draw(tmp_path / "first" / "graph", seed=1)
    draw(tmp_path / "second" / "graph", seed=2)
    for suffix in (".svg", ".png"):
        first = (tmp_path / "first" / "graph").with_suffix(suffix).read_bytes()
        second = (tmp_path / "second" / "graph").with_suffix(suffix).read_bytes()
        assert len(first) > 10_000 and first == second, suffix
