"""benchmarks/contact_peer.py builds the same scenes as the CONTACT inputs it writes.

Cheap (no solve): the jaxcontact scene and CONTACT's input text of Spence's problem and
of the Cattaneo-Mindlin load have the same grid (cell centres relative to the sphere, as
CONTACT reads them: its grid line has 7 decimals), sphere, material, friction and load
stages, which are the generator's to its print precision; and the `.mat` reader
indexes elements as CONTACT writes them (`m_soutpt.f90`: `jj = ix + nx (jy - 1)`,
interior elements in contact only, IGS 1 = adhesion, 2 = slip).
"""

import importlib.util
import re
from pathlib import Path

import numpy as np
import pytest


ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def peer():
    spec = importlib.util.spec_from_file_location(
        "contact_peer", ROOT / "benchmarks" / "contact_peer.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _floats(line):
    return [float(v) for v in line.split()]


def _parse_input(text):
    """Grid, quadratic gap, material and the FN of every stage of a CONTACT input."""
    lines = text.splitlines()
    grid = next(line for line in lines if "MX,MY,XL,YL,DX,DY" in line)
    mx, my, xl, yl, dx, dy = _floats(grid.split("MX")[0])
    b = _floats(
        next(
            lines[i + 1]
            for i, line in enumerate(lines)
            if "UNDEFORMED DISTANCE" in line
        ).split("B(I)")[0]
    )
    poiss = _floats(
        next(line for line in lines if "POISS 1,2" in line).split("POISS")[0]
    )
    fric = _floats(
        next(line for line in lines if "FSTAT, FKIN" in line).split("FSTAT")[0]
    )
    loads = [
        _floats(line.split("FN")[0])
        for line in lines
        if re.search(r"\bFN, (CKSI|FX)", line)
    ]
    return dict(
        mx=int(mx),
        my=int(my),
        xl=xl,
        yl=yl,
        dx=dx,
        dy=dy,
        b=b,
        poiss=poiss,
        fric=fric,
        loads=np.array(loads),
    )


def _check_grid(scene, inp):
    m = scene.grid.shape[0]
    assert scene.grid.shape == (inp["mx"], inp["my"])
    np.testing.assert_allclose(
        np.asarray(scene.grid.spacing), [inp["dx"], inp["dy"]], rtol=1e-6
    )
    # cell centres relative to the sphere's centre, jaxcontact against CONTACT
    centres = (np.arange(m) - (m - 1) / 2) * float(scene.grid.spacing[0])
    relative = centres - float(scene.indenter.centre[0])
    contact = inp["xl"] + (np.arange(m) + 0.5) * inp["dx"]
    np.testing.assert_allclose(relative, contact, rtol=0, atol=1e-12)
    # CONTACT's shift of +5e-4 dx, changed by the rounding of DX and XL to 7 decimals
    assert 0 < -float(scene.indenter.centre[0]) < 1e-3 * inp["dx"]
    np.testing.assert_allclose(
        1 / (2 * float(scene.indenter.radius)), [inp["b"][0], inp["b"][2]], rtol=1e-7
    )
    assert float(scene.material.poisson) == pytest.approx(inp["poiss"][0])
    assert float(scene.material.shear_modulus) == pytest.approx(inp["poiss"][2])
    assert float(scene.friction) == pytest.approx(inp["fric"][0])


def test_spence_scene_matches_contact_input(peer):
    text, meta = peer.contact_inputs.spence_input(0.25, 0.3, 45, 5)
    scene = peer.spence_scene(text)
    inp = _parse_input(text)
    assert inp["mx"] == 2 * round(1.25 * 45) + 1 == meta["M"]
    assert inp["dx"] == pytest.approx(1 / 45, rel=2e-6)  # printed 0.0222222
    _check_grid(scene, inp)
    assert scene.coupling == "full" and scene.slip == "incremental"
    assert scene.x is None and scene.y is None
    fn = np.asarray(scene.normal.values(scene.times))
    assert fn.shape == (5,) and inp["loads"].shape[0] == 5
    np.testing.assert_allclose(fn, inp["loads"][:, 0], rtol=1e-8)
    np.testing.assert_allclose(fn, meta["F_final"] * (np.arange(1, 6) / 5) ** 3)
    assert np.all(inp["loads"][:, 1:] == 0)  # CKSI = CETA = CPHI = 0: no shift


def test_cattaneo_scene_matches_contact_input(peer):
    text, meta = peer.contact_inputs.cattaneo_input(6)
    scene = peer.cattaneo_scene(text)
    inp = _parse_input(text)
    assert inp["dx"] == pytest.approx(meta["dx"], rel=1e-6)
    _check_grid(scene, inp)
    assert scene.coupling == "none" and scene.times.shape == (1,)
    ((fn, fx_rel, fy, _),) = inp["loads"]
    assert float(scene.normal.values(scene.times)[0]) == pytest.approx(fn)
    assert float(scene.x.values(scene.times)[0]) == pytest.approx(
        fx_rel * inp["fric"][0] * fn
    )
    # F_y = 0 prescribed (q_y solved for, as CONTACT does), not y=None (q_y = 0)
    assert fy == 0 and float(scene.y.values(scene.times)[0]) == 0.0
    assert scene.tangential_directions == 2


def test_read_mat_indexing(peer, tmp_path):
    mat = tmp_path / "case.0001.mat"
    mat.write_text(
        "%  header\n   1 2 3\n%    I    IGS    H   MU   PN\n"
        "      2    1    0.1  0.2  0.3\n"  # ix = 2, iy = 1: adhesion
        "      7    2    0.1  0.2  0.3\n"
    )  # ix = 1, iy = 3 (m = 3): slip
    contact, stick = peer.read_mat(mat, 3)
    assert sorted(zip(*np.nonzero(contact))) == [(0, 2), (1, 0)]
    assert sorted(zip(*np.nonzero(stick))) == [(1, 0)]
