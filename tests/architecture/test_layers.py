"""The layers of docs/architecture.md hold in the code: no module uses one of a higher layer
(folder), and the module graph has no cycle. The checks see a planted upward `use`, a planted
cycle and a file in no layer in a copy of the sources, and read a subfolder as a folder of its
layer. (The pictures: test_module_graph_reproducible.py.)"""
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(Path(__file__).resolve().parent))

import module_graph  # noqa: E402


def test_the_code_keeps_its_layers_and_has_no_cycle():
    nodes, edges = module_graph.graph(ROOT)
    assert len(nodes) > 60 and len(edges) > 200          # the whole code was read
    assert module_graph.unlayered(nodes) == []
    assert module_graph.upward(nodes, edges) == []
    assert module_graph.cycles(nodes, edges) == []
    # Fortran's calls of C are edges too: the HDF5 files call the storage shim.
    assert ("hdf5_files", "hdf5_storage.c") in edges


@pytest.fixture
def copy(tmp_path):
    for folder in ("src", "drivers"):
        shutil.copytree(ROOT / folder, tmp_path / folder)
    return tmp_path


def shared_element(folder):
    """Whether a folder of src/model/ is a shared element, not a model: its description is
    `potential_only` (the generator writes the element's potentials alone, which models' own code
    assembles, as src/model/paper_spring/'s spring serves the chain and the pendulum's kernel)."""
    description = folder / "description.py"
    return description.exists() and "model.potential_only = True" in description.read_text()


def foreign_uses_of_model_rooms(root):
    """Uses of a module in a model's own folder (src/model/NAME/) from outside that folder, other
    than the registry's lines (model_registry_lines, a model's one registration line) and the
    drivers'. A shared element's folder is no model's room: any model may use it."""
    nodes, edges = module_graph.graph(root)
    model_root = root / "src" / "model"

    def room(name):
        path = nodes[name][1]
        return path.parent if path.parent != model_root and model_root in path.parents else None

    return sorted((user, used) for user, used in edges
                  if room(used) is not None and room(user) != room(used) and not shared_element(room(used))
                  and user != "model_registry_lines" and nodes[user][0] != "drivers")


def test_a_model_keeps_to_its_folder():
    """No module outside a model's folder uses the model's modules (the engine speaks no
    pendulum): the pendulum's modules are used from src/model/pendulum/, the registry and the
    drivers only."""
    assert (ROOT / "src" / "model" / "pendulum" / "pendulum_rungs.f90").exists()
    assert foreign_uses_of_model_rooms(ROOT) == []


def test_a_planted_use_of_a_model_module_is_found(copy):
    text = (copy / "src" / "integrator" / "relaxed_stepper.f90").read_text()
    (copy / "src" / "integrator" / "relaxed_stepper.f90").write_text(
        text.replace("  implicit none", "  use pendulum_rungs, only: rung_model\n  implicit none", 1))
    assert foreign_uses_of_model_rooms(copy) == [("relaxed_stepper", "pendulum_rungs")]


def test_another_model_uses_nothing_of_the_pendulum(copy):
    """The spring chain's springs and the pendulum's fused kernel both run on the shared element of
    the paper's spring (src/model/paper_spring/description.py), not on each other's code; a planted
    use of the pendulum's kernel from the chain's folder is found."""
    edges = module_graph.graph(copy)[1]
    assert ("spring_chain_spring", "paper_spring_potential") in edges
    assert ("pendulum_step_kernel", "paper_spring_potential") in edges
    assert shared_element(copy / "src" / "model" / "paper_spring")
    assert not shared_element(copy / "src" / "model" / "pendulum")
    path = copy / "src" / "model" / "spring_chain" / "spring_chain_step.f90"
    path.write_text(path.read_text().replace("  implicit none", "  use pendulum_step_kernel, only: pendulum_step\n  implicit none", 1))
    assert foreign_uses_of_model_rooms(copy) == [("spring_chain_step", "pendulum_step_kernel")]


def test_a_shared_element_uses_no_model(copy):
    """The shared element is used by models and uses none of them: a planted use of the chain's
    module in the element is found."""
    path = copy / "src" / "model" / "paper_spring" / "paper_spring_potential.f90"
    path.write_text(path.read_text().replace("  implicit none", "  use spring_chain_layout, only: slots_of\n  implicit none", 1))
    assert foreign_uses_of_model_rooms(copy) == [("paper_spring_potential", "spring_chain_layout")]


def test_a_planted_upward_use_is_found(copy):
    text = (copy / "src" / "util" / "number_text.f90").read_text()
    (copy / "src" / "util" / "number_text.f90").write_text(
        text.replace("  implicit none", "  use simulation, only: run_simulation\n  implicit none", 1))
    result = subprocess.run([sys.executable, str(ROOT / "tests" / "architecture" / "module_graph.py"), "--check",
                             "--root", str(copy)], capture_output=True, text=True)
    assert result.returncode == 1
    assert "number_text (util) uses simulation (run), a higher layer" in result.stdout


def test_a_planted_cycle_is_found(copy):
    text = (copy / "src" / "util" / "statistics.f90").read_text()
    (copy / "src" / "util" / "statistics.f90").write_text(
        text.replace("  implicit none", "  use number_text, only: integer_text\n  implicit none", 1))
    text = (copy / "src" / "util" / "number_text.f90").read_text()
    (copy / "src" / "util" / "number_text.f90").write_text(
        text.replace("  implicit none", "  use statistics, only: median\n  implicit none", 1))
    nodes, edges = module_graph.graph(copy)
    cycle = module_graph.cycles(nodes, edges)
    assert set(cycle) == {"number_text", "statistics"}


def test_a_subfolder_is_a_folder_of_its_layer(copy):
    # A second model in a folder of its own, beside src/model/pendulum/.
    (copy / "src" / "model" / "spring").mkdir()
    (copy / "src" / "model" / "spring" / "spring_model.f90").write_text(
        "module spring_model\n  use model_interface, only: model\n  use model_scene, only: scene\n"
        "  implicit none\nend module spring_model\n")
    nodes, edges = module_graph.graph(copy)
    assert (nodes["spring_model"].layer, nodes["spring_model"].folder) == ("model", "model/spring")
    assert (nodes["pendulum_rungs"].layer, nodes["pendulum_rungs"].folder) == ("model", "model/pendulum")
    assert (nodes["model_registry"].layer, nodes["model_registry"].folder) == ("model", "model")
    files, counts = module_graph.folder_graph(nodes, edges)
    folders = list(files)
    band = [folder for folder in folders if module_graph.layer_of(folder) == "model"]
    start = folders.index("model")                          # one band: the layer's folder, then each model's
    assert folders[start:start + len(band)] == band == sorted(band) and band[0] == "model"
    assert {"model/pendulum", "model/spring"} <= set(band)
    assert files["model/spring"] == 1
    assert counts[("model/spring", "model")] == counts[("model/spring", "structure")] == 1
    assert sum(counts.values()) == len(edges)


def test_a_file_in_no_layer_is_found(copy):
    (copy / "src" / "extras").mkdir()
    (copy / "src" / "extras" / "stray.f90").write_text("module stray\n  implicit none\nend module stray\n")
    result = subprocess.run([sys.executable, str(ROOT / "tests" / "architecture" / "module_graph.py"), "--check",
                             "--root", str(copy)], capture_output=True, text=True)
    assert result.returncode == 1
    assert "src/extras/stray.f90 is in src/extras, which is in no layer" in result.stdout
