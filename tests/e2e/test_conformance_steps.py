"""check_steps of the conformance kit (docs/development.md, Adding a model): every registered model
(as `eme_run --help` names them) with every registered integrator (`eme_run --integrators`), each
from its scene's defaults. Every pair completes; an integrator whose registry entry says it keeps
the structure (keeps_structure: EME, the relaxed schemes) keeps it on every step: E to 64 eps |E_0|,
dS >= -32 eps max|S|, dV <= 64 eps |E_0| (the README's round-off bounds), and the model's conserved
momentum (the root attribute conserved_momentum names its column) to 64 eps of its scale. A new
model or integrator is tested here by its registry line alone. The pendulum's rungs (spring_law,
dimension; docs/formulation.md section 9) run beside the registered models' defaults; a model
without temperatures (elastic springs) has no entropy to check."""
import re
import subprocess

import h5py
import numpy as np
import pytest

from conftest import BIN, run_eme

EPS = np.finfo(float).eps


def models():
    text = subprocess.run([str(BIN / "eme_run"), "--help"], capture_output=True, text=True, check=True).stdout
    return re.search(r"The models: ([\w ]+)\.", " ".join(text.split())).group(1).split()


def integrators():
    lines = subprocess.run([str(BIN / "eme_run"), "--integrators"], capture_output=True, text=True,
                           check=True).stdout.splitlines()
    header = lines[0].split("\t")
    return [dict(zip(header, line.split("\t"))) for line in lines[1:]]


def test_the_registries_are_read():
    assert {"double_pendulum", "gas_containers"} <= set(models())
    assert len(integrators()) >= 12 and any(entry["keeps_structure"] == "yes" for entry in integrators())


def scenes():
    """Each registered model at its defaults, and the pendulum's rungs."""
    pendulum_rungs = {
        "pendulum thermoelastic": {"spring_law": "thermoelastic"},
        "pendulum planar": {"dimension": 2},
        "pendulum thermoelastic planar": {"spring_law": "thermoelastic", "dimension": 2, "gravity": [0.0, 0.0]},
        "pendulum elastic": {"spring_law": "elastic"},
        "pendulum elastic planar": {"spring_law": "elastic", "dimension": 2, "gravity": [0.0, 0.0]},
    }
    return {**{model: {"model_name": model} for model in models()}, **pendulum_rungs}


@pytest.mark.parametrize("scene", scenes())
@pytest.mark.parametrize("entry", integrators(), ids=lambda entry: entry["name"])
def test_every_step_of_every_model_and_integrator(tmp_path, scene, entry):
    integrator = {"scheme": entry["name"], "dt": 0.05, "t_end": 3.0}
    if entry["adaptive"] == "yes":
        integrator["tolerance"] = 1e-8
    result, path = run_eme(tmp_path, "run", {"model": scenes()[scene], "integrator": integrator})
    assert result.returncode == 0, result.stderr
    with h5py.File(path, "r") as f:
        assert f.attrs["status"] == "complete"
        if entry["keeps_structure"] != "yes":
            return
        energy = f["energy"][()]
        scale = abs(energy[0])
        assert np.abs(energy - energy[0]).max() <= 64 * EPS * scale, np.abs(energy - energy[0]).max() / (EPS * scale)
        if "entropy" in f:
            entropy = f["entropy"][()]
            assert f["min_entropy_increment"][()].min() >= -32 * EPS * np.abs(entropy).max()
            assert f["max_lyapunov_increment"][()].max() <= 64 * EPS * scale
        else:
            assert "temperature" not in f and "lyapunov" not in f, sorted(f)
        conserved = f.attrs["conserved_momentum"]
        conserved = conserved.decode() if isinstance(conserved, bytes) else conserved
        if conserved != "none":
            momenta = f["angular_momentum"]
            column = momenta.attrs["columns"]
            column = (column.decode() if isinstance(column, bytes) else column).split().index(conserved)
            values = momenta[:, column]
            assert np.abs(values - values[0]).max() <= 64 * EPS * max(np.abs(momenta[()]).max(), 1.0)
