"""check_steps of the conformance kit (docs/development.md, Adding a model): every registered model
(as `eme_run --help` names them) with every registered integrator (`eme_run --integrators`), each
from its scene's defaults. Every pair completes; an integrator whose registry entry says it keeps
the structure (keeps_structure: EME, the relaxed schemes) keeps it on every step: E to 64 eps |E_0|,
dS >= -32 eps max|S|, dV <= 64 eps |E_0| (the README's round-off bounds), and each of the model's
conserved momentum components (the root attribute conserved_momentum names them: a column of
/angular_momentum, or J_g, J dotted with its axis in conserved_momentum_axes) to 64 eps of its
scale. A new model or integrator is tested here by its registry line alone. The pendulum's rungs
(spring_law, dimension; docs/formulation.md section 9) and its spatial scene without gravity (J_x,
J_y and J_z all kept) and under gravity off the axes (J_g) run beside the registered models'
defaults, the last two from a state off the plane of the paper's; a model without temperatures
(elastic springs) has no entropy to check."""
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
    """Each registered model at its defaults, and the pendulum's rungs and gravities (namelist groups)."""
    off_plane = {"q1": [1.0, 0.0, 0.5]}
    pendulum_rungs = {
        "pendulum thermoelastic": {"model": {"spring_law": "thermoelastic"}},
        "pendulum planar": {"model": {"dimension": 2}},
        "pendulum thermoelastic planar": {"model": {"spring_law": "thermoelastic", "dimension": 2,
                                                    "gravity": [0.0, 0.0]}},
        "pendulum elastic": {"model": {"spring_law": "elastic"}},
        "pendulum elastic planar": {"model": {"spring_law": "elastic", "dimension": 2, "gravity": [0.0, 0.0]}},
        "pendulum no gravity": {"model": {"gravity": [0.0, 0.0, 0.0]}, "initial": off_plane},
        "pendulum oblique gravity": {"model": {"gravity": [3.0, -4.0, -8.0]}, "initial": off_plane},
    }
    return {**{model: {"model": {"model_name": model}} for model in models()}, **pendulum_rungs}


@pytest.mark.parametrize("scene", scenes())
@pytest.mark.parametrize("entry", integrators(), ids=lambda entry: entry["name"])
def test_every_step_of_every_model_and_integrator(tmp_path, scene, entry):
    integrator = {"scheme": entry["name"], "dt": 0.05, "t_end": 3.0}
    if entry["adaptive"] == "yes":
        integrator["tolerance"] = 1e-8
    result, path = run_eme(tmp_path, "run", {**scenes()[scene], "integrator": integrator})
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
        for name, values in conserved_components(f).items():
            scale = max(np.abs(f["angular_momentum"][()]).max(), 1.0)
            assert np.abs(values - values[0]).max() <= 64 * EPS * scale, (name, np.abs(values - values[0]).max())


def conserved_components(f):
    """{name: values} of the file's conserved momentum components: the column of that name, or J_x
    J_y J_z dotted with the component's axis (J_g)."""
    text = f.attrs["conserved_momentum"]
    names = (text.decode() if isinstance(text, bytes) else text).split()
    if names == ["none"]:
        return {}
    momenta = f["angular_momentum"]
    columns = momenta.attrs["columns"]
    columns = (columns.decode() if isinstance(columns, bytes) else columns).split()
    axes = np.reshape(f.attrs["conserved_momentum_axes"], (-1, 3))
    assert len(axes) == len(names) and np.allclose(np.linalg.norm(axes, axis=1), 1.0)
    return {name: momenta[:, columns.index(name)] if name in columns else momenta[()] @ axis
            for name, axis in zip(names, axes)}
