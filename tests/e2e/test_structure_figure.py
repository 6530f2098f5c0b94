"""The paper's Fig. 2 from the code's own matrices: eme_structure writes L and K of eq. (8) at the
paper scene's initial state for tau = s, theta, u, and the file says what the paper says of them:
with the entropy only the canonical Hamilton block of L is occupied (L = [[0, I], [-I, 0]] on
(q, p)) and K acts on gamma and tau alone; the temperature occupies a superset of the others'
entries; L is skew, K symmetric positive semidefinite; and the degeneracy conditions L grad S = 0
and K grad E = 0 hold at that state. plot_structure.py draws it."""
import subprocess
import sys

import h5py
import numpy as np
import pytest

from conftest import BIN, ROOT

VARIABLES = ("entropy", "temperature", "internal_energy")
Q, P, GAMMA, TAU = slice(0, 6), slice(6, 12), slice(12, 13), slice(13, 15)


@pytest.fixture(scope="module")
def structure(tmp_path_factory):
    path = tmp_path_factory.mktemp("structure") / "structure.h5"
    result = subprocess.run([str(BIN / "eme_structure"), str(ROOT / "inputs" / "paper_fig3.nml"), str(path)],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    with h5py.File(path, "r") as f:
        data = {v: {name: f[v][name][()] for name in ("L", "K", "grad_E", "grad_S", "state")} for v in VARIABLES}
        columns = f["temperature"]["L"].attrs["columns"]
    return path, data, (columns.decode() if isinstance(columns, bytes) else columns).split()


def test_the_state_layout_is_the_run_files(structure):
    _, data, columns = structure
    assert columns[:13] == "q1_x q1_y q1_z q2_x q2_y q2_z p1_x p1_y p1_z p2_x p2_y p2_z gamma".split()
    assert columns[13:] == ["theta_1", "theta_2"]
    np.testing.assert_allclose(data["temperature"]["state"][13:], [280.0, 350.0])


def test_entropy_occupies_only_the_canonical_block_of_l(structure):
    _, data, _ = structure
    l = data["entropy"]["L"]
    np.testing.assert_array_equal(l[Q, P], np.eye(6))
    np.testing.assert_array_equal(l[P, Q], -np.eye(6))
    occupied = l != 0
    occupied[Q, P] = occupied[P, Q] = False
    assert not occupied.any(), np.argwhere(occupied)
    k = data["entropy"]["K"]
    assert not k[:12].any() and not k[:, :12].any()     # dissipation acts on gamma and tau only
    assert k[GAMMA, GAMMA][0, 0] > 0 and k[TAU, TAU].any()


def test_the_temperature_occupies_a_superset_of_the_others(structure):
    _, data, _ = structure
    for name in ("L", "K"):
        theta = data["temperature"][name] != 0
        for other in ("entropy", "internal_energy"):
            assert not (data[other][name] != 0)[~theta].any(), (name, other)
    # ... and strictly more than the entropy's L: the momenta couple to the temperatures.
    assert (data["temperature"]["L"] != 0).sum() > (data["entropy"]["L"] != 0).sum()
    assert data["temperature"]["L"][P, TAU].any()


@pytest.mark.parametrize("variable", VARIABLES)
def test_l_is_skew_k_positive_semidefinite_and_both_degenerate(structure, variable):
    _, data, _ = structure
    l, k, grad_e, grad_s = (data[variable][name] for name in ("L", "K", "grad_E", "grad_S"))
    np.testing.assert_array_equal(l, -l.T)
    np.testing.assert_allclose(k, k.T, rtol=0, atol=1e-14 * np.abs(k).max())
    assert np.linalg.eigvalsh(k).min() >= -1e-13 * np.abs(k).max()
    # Degeneracy (5): L grad S = 0 and K grad E = 0, to the rounding of the products.
    assert np.abs(l @ grad_s).max() <= 1e-13 * np.abs(l).max() * np.abs(grad_s).max()
    assert np.abs(k @ grad_e).max() <= 1e-13 * np.abs(k).max() * np.abs(grad_e).max()
    assert np.abs(grad_s).max() > 0 and np.abs(grad_e).max() > 0


@pytest.mark.drawing
def test_the_figure_is_drawn(structure, tmp_path):
    path, data, _ = structure
    output = tmp_path / "fig2"
    result = subprocess.run([sys.executable, str(ROOT / "postprocess" / "plot_structure.py"), str(path), "-o",
                             str(output)], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert output.with_suffix(".png").read_bytes().startswith(b"\x89PNG")
    assert output.with_suffix(".pdf").read_bytes().startswith(b"%PDF")
    caption = output.with_suffix(".txt").read_text()
    assert f"entropy: nonzero entries L {np.count_nonzero(data['entropy']['L'])}" in caption


def test_bad_usage_writes_nothing(tmp_path):
    result = subprocess.run([str(BIN / "eme_structure"), str(tmp_path / "missing.nml"), str(tmp_path / "out.h5")],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 2 and "missing.nml" in result.stderr
    assert not (tmp_path / "out.h5").exists()
    assert subprocess.run([str(BIN / "eme_structure")], capture_output=True, text=True).returncode == 2
