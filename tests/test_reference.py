"""The float64 reference tracer, against hand derivations and optical reversibility."""

import json
import subprocess
import sys

import numpy as np
import pytest

from realistic import LensSystem, load_lens, parse_prescription
from realistic.optics.paraxial import film_distance_for_focus
from realistic.optics.tracer import APERTURE, MISS, PASSED, STOP, TIR, trace_from_film

LENSES = ["dgauss", "wide", "fisheye", "telephoto", "dgauss100"]


def snell_vector(incident, normal, n1, n2):
    """Refraction by the cross-product form of Snell's law; ``normal`` faces the incident ray."""
    mu = n1 / n2
    cross = np.cross(normal, incident)
    return mu * np.cross(normal, np.cross(-normal, incident)) - normal * np.sqrt(1 - mu * mu * cross @ cross)


def test_single_surface_against_hand_derivation():
    # One spherical surface, glass (n = 1.5) on the film side, and a stop 5 mm in front of it.
    radius, film_distance = -30.0, 20.0
    lens = parse_prescription(f"0 5 0 40\n{radius} 0 1.5 40\n")
    rng = np.random.default_rng(3)
    for _ in range(50):
        origin = np.array([*rng.uniform(-3, 3, 2), 0.0])
        direction = np.array([*rng.uniform(-0.3, 0.3, 2), 1.0])
        direction /= np.linalg.norm(direction)
        # Hand derivation: the sphere's centre sits at z = 20 + 30; solve |o + t d - c|^2 = R^2 for the
        # root nearer the film (R < 0: the vertex is the sphere's point closest to the film).
        centre = np.array([0.0, 0.0, film_distance - radius])
        coeffs = [1.0, 2 * direction @ (origin - centre), (origin - centre) @ (origin - centre) - radius**2]
        t = min(r.real for r in np.roots(coeffs))
        hit = origin + t * direction
        outward = (hit - centre) / abs(radius)
        facing = -outward if outward @ direction > 0 else outward
        refracted = snell_vector(direction, facing, 1.5, 1.0)
        on_stop = hit + (film_distance + 5 - hit[2]) / refracted[2] * refracted
        result = trace_from_film(lens, film_distance, origin[None], direction[None])
        assert result.blocked_reason[0] == PASSED
        np.testing.assert_allclose(result.origin[0], on_stop, atol=1e-9)
        np.testing.assert_allclose(result.direction[0], refracted, atol=1e-12)


def reversed_lens(lens: LensSystem) -> LensSystem:
    """The lens seen from the scene side, as a new prescription (for the reversibility test)."""
    n = lens.surface_count
    index = np.concatenate([lens.index_d[-2::-1], [1.0]])
    thickness = np.concatenate([lens.thickness_mm[-2::-1], [0.0]])
    return LensSystem("reversed", -lens.radius_mm[::-1], thickness, index, lens.abbe_v[::-1] * 0,
                      lens.aperture_mm[::-1], n - 1 - lens.stop)


@pytest.mark.parametrize("name", LENSES)
def test_optical_reversibility(name):
    lens = load_lens(name)
    film = film_distance_for_focus(lens, 5000.0)
    rng = np.random.default_rng(7)
    count = 4000
    origins = np.column_stack([rng.uniform(-10, 10, (count, 2)), np.zeros(count)])
    rear_radius = lens.aperture_mm[-1] / 2
    targets = np.column_stack([rng.uniform(-rear_radius, rear_radius, (count, 2)), np.full(count, film)])
    forward = trace_from_film(lens, film, origins, targets - origins)
    ok = forward.passed
    assert ok.sum() > 100
    front_z = film + lens.track_length_mm
    gap = 7.0  # the reversed lens's "film" is 7 mm in front of the original front vertex
    flip = np.array([1.0, 1.0, -1.0])
    start = forward.origin[ok] + 3.0 * forward.direction[ok]
    start_rev = start * flip + [0, 0, front_z + gap]
    back = trace_from_film(reversed_lens(lens), gap, start_rev, -forward.direction[ok] * flip)
    assert back.passed.all()
    landing = back.origin + (front_z + gap - back.origin[:, 2:3]) / back.direction[:, 2:3] * back.direction
    np.testing.assert_allclose(landing[:, :2], origins[ok, :2], atol=1e-9)


@pytest.mark.parametrize("name", LENSES)
def test_rotational_symmetry(name):
    lens = load_lens(name)
    film = film_distance_for_focus(lens, 5000.0)
    rng = np.random.default_rng(11)
    o = np.column_stack([rng.uniform(-8, 8, (500, 2)), np.zeros(500)])
    d = np.column_stack([rng.uniform(-0.4, 0.4, (500, 2)), np.ones(500)])
    angle = 0.7
    rot = np.array([[np.cos(angle), -np.sin(angle), 0], [np.sin(angle), np.cos(angle), 0], [0, 0, 1]])
    a = trace_from_film(lens, film, o, d)
    b = trace_from_film(lens, film, o @ rot.T, d @ rot.T)
    np.testing.assert_array_equal(a.blocked_reason, b.blocked_reason)
    np.testing.assert_allclose(b.origin[a.passed], a.origin[a.passed] @ rot.T, atol=1e-9)
    np.testing.assert_allclose(b.direction[a.passed], a.direction[a.passed] @ rot.T, atol=1e-12)


@pytest.mark.parametrize("name", LENSES)
def test_axial_point_at_focal_plane_leaves_collimated(name):
    lens = load_lens(name)
    film = film_distance_for_focus(lens, np.inf)
    tiny = np.array([[1e-5, 0, 1], [0, -2e-5, 1], [1.5e-5, 1e-5, 1]])
    result = trace_from_film(lens, film, np.zeros((3, 3)), tiny)
    assert result.passed.all()
    assert np.abs(result.direction[:, :2]).max() < 1e-9  # paraxial rays from the focal point exit parallel


def test_blocking_reasons():
    lens = parse_prescription("0 5 0 4\n-30 0 1.5 40\n")
    origins = np.zeros((4, 3))
    origins[2, 2] = 19.9  # just behind the vertex, so the steep ray meets the sphere
    directions = np.array([
        [0.0, 0.0, 1.0],  # passes
        [0.3, 0.0, 1.0],  # refracted outward, lands outside the 4 mm stop
        [1.2, 0.0, 1.0],  # steep in glass: total internal reflection at the sphere
        [0.0, 0.0, -1.0],  # travels away from the lens
    ])
    result = trace_from_film(lens, 20.0, origins, directions)
    assert result.blocked_reason.tolist() == [PASSED, STOP, TIR, MISS]
    assert result.blocked_surface.tolist() == [-1, 0, 1, 1]
    narrow = parse_prescription("0 5 0 30\n-30 0 1.5 4\n")
    assert trace_from_film(narrow, 20.0, origins[:2], directions[:2]).blocked_reason.tolist() == [PASSED, APERTURE]


def test_cli_trace_writes_documented_json(tmp_path):
    rays = {"rays": [{"origin": [0, 0, 0], "direction": [0, 0, 1]}, {"origin": [0, 0, 0], "direction": [0.4, 0, 1]}]}
    src, out = tmp_path / "rays.json", tmp_path / "out.json"
    src.write_text(json.dumps(rays))
    run = subprocess.run([sys.executable, "-m", "realistic", "lens", "trace", "dgauss", "--film-distance", "36.77",
                          "--input", str(src), "--output", str(out)], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    result = json.loads(out.read_text())["rays"]
    lens = load_lens("dgauss")
    assert result[0]["origin"] == pytest.approx([0, 0, 36.77 + lens.track_length_mm])
    assert result[0]["direction"] == pytest.approx([0, 0, 1])
    assert result[1]["blocked_by"] == {"surface": 10, "reason": "aperture"}


def test_cli_trace_rejects_bad_json(tmp_path):
    src = tmp_path / "rays.json"
    src.write_text('{"rays": [{"origin": [0, 0], "direction": [0, 0, 1]}]}')
    run = subprocess.run([sys.executable, "-m", "realistic", "lens", "trace", "dgauss", "--film-distance", "36.77",
                          "--input", str(src)], capture_output=True, text=True)
    assert run.returncode == 2
    assert "rays[0].origin" in run.stderr and "Traceback" not in run.stderr
