"""``lens plot`` as optics programs draw a lens (scene left, film right, axis horizontal), and the
warning when spot or MTF asks for colours a lens has no dispersion data for."""

import dataclasses
import subprocess
import sys
from pathlib import Path

import numpy as np

from realistic import load_lens
from realistic.optics import drawing
from realistic.optics.paraxial import film_distance_for_focus

REPO = Path(__file__).resolve().parents[1]


def test_cross_section_has_the_scene_on_the_left_and_the_film_on_the_right(monkeypatch, tmp_path):
    figures = []
    monkeypatch.setattr(drawing, "save_figure", lambda fig, out, dpi: figures.append(fig))
    lens = load_lens("dgauss")
    film = film_distance_for_focus(lens, 5000.0)
    drawing.plot_cross_section(lens, film, tmp_path / "x.png")
    (ax,) = figures[0].axes
    left, right = ax.get_xlim()
    front = lens.vertex_z_mm(film)[0]
    # the x axis holds the lens frame's z (film at 0, +z toward the scene), running right to left
    assert left > front > 0 >= right
    assert ax.transData.transform((front, 0))[0] < ax.transData.transform((0, 0))[0]
    # the optical axis is horizontal: the dashed axis line has one height
    axis = [line for line in ax.get_lines() if line.get_linestyle() == "--"]
    assert axis and np.ptp(axis[0].get_ydata()) == 0


def _cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "realistic", *args], cwd=REPO, capture_output=True, text=True,
                          timeout=600)


def test_spot_warns_when_the_lens_has_no_dispersion_data(tmp_path):
    result = _cli("lens", "spot", "tessar.100mm", "--wavelengths", "F,d,C", "--samples", "8",
                  "--out", str(tmp_path / "s.png"))
    assert result.returncode == 0, result.stderr
    assert "no glass has dispersion data" in result.stderr and "tessar.100mm" in result.stderr
    quiet = _cli("lens", "spot", "tessar.100mm", "--wavelengths", "d", "--samples", "8",
                 "--out", str(tmp_path / "d.png"))
    assert quiet.returncode == 0 and "dispersion" not in quiet.stderr


def test_lens_with_dispersion_and_a_glass_without_is_named_by_surface():
    lens = load_lens("dgauss")
    assert lens.dispersion_warning([486.1327, 656.2725]) is None
    abbe = lens.abbe_v.copy()
    glass = int(np.flatnonzero(lens.index_d != 1)[1])
    abbe[glass] = 0.0
    warning = dataclasses.replace(lens, abbe_v=abbe).dispersion_warning([486.1327])
    assert warning is not None and f"surface {glass} has no dispersion data" in warning
