"""make docs draws the folder graph and the module graph (docs/architecture/); with no source
change the redrawn files are the same bytes, so a second make docs leaves `git status` clean (the
SVG had a date and random clip-path ids in it). Each drawing runs in a process of its own, as make
docs runs it (its own hash seed). Each file carries a description of the graph it was drawn from,
so the committed pictures are checked against the sources without comparing pixels; and the
numbers on the folder graph's arrows are the counts of edges between the folders."""
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(Path(__file__).resolve().parent))

import module_graph  # noqa: E402

pytestmark = pytest.mark.drawing
PICTURES = ("folder_graph", "module_graph")


def draw(output, seed):
    environment = {**os.environ, "PYTHONHASHSEED": str(seed)}
    result = subprocess.run([sys.executable, str(ROOT / "tests" / "architecture" / "module_graph.py"), "-o",
                             str(output)], capture_output=True, text=True, timeout=600, env=environment)
    assert result.returncode == 0, result.stderr


def test_two_drawings_of_the_same_sources_are_the_same_bytes(tmp_path):
    draw(tmp_path / "first", seed=1)
    draw(tmp_path / "second", seed=2)
    for name in PICTURES:
        for suffix, start in ((".svg", b"<?xml"), (".png", b"\x89PNG")):
            first, second = ((tmp_path / run / name).with_suffix(suffix).read_bytes() for run in ("first", "second"))
            assert first.startswith(start) and len(first) > 10_000 and first == second, name + suffix


def test_the_committed_pictures_are_drawn_from_the_current_sources():
    expected = module_graph.descriptions(*module_graph.graph(ROOT))
    for name in PICTURES:
        path = ROOT / "docs" / "architecture" / name
        assert module_graph.described(path.with_suffix(".svg").read_text()) == expected[name], \
            f"{path}.svg is out of date: run make docs"
        assert f"Description\0{expected[name]}".encode() in path.with_suffix(".png").read_bytes(), \
            f"{path}.png is out of date: run make docs"


def test_the_folder_graph_shows_every_folder_and_its_counts():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot

    nodes, edges = module_graph.graph(ROOT)
    fig, _ = module_graph.draw_folders(nodes, edges)
    texts = [text.get_text() for text in fig.axes[0].texts]
    files, counts = module_graph.folder_graph(nodes, edges)
    for folder, n in files.items():
        assert module_graph.box_label(folder) in texts
        assert module_graph.box_counts(n, counts.get((folder, folder), 0)) in texts
    # One number per arrow, each the count of its pair of folders (both ways where two folders use
    # each other, as the model and its subfolder do).
    numbers = sorted(int(text) for text in texts if text.isdigit())
    assert numbers == sorted(n for (a, b), n in counts.items() if a != b)
    assert len(numbers) > 25
    matplotlib.pyplot.close(fig)
