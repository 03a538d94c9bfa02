"""Ghost paths (realistic.optics.ghosts) against conservation of energy, the plate's closed forms and
the symmetry of the lens."""

from __future__ import annotations

import math
from collections import defaultdict

import numpy as np
import pytest

from realistic import load_lens
from realistic.errors import UserError
from realistic.optics.coating import IDEAL, reflect_transmit
from realistic.optics.ghosts import GhostPath, GhostTrace, ghost_paths, path_steps, summarise, trace_direct, trace_ghost
from realistic.optics.lens import LensSystem, build_lens
from realistic.optics.paraxial import paraxial_data
from realistic.optics.tracer import Vectors, incidence_cosine, intersect_surface, refract

WAVELENGTH = 587.56


def _lens(rows: list[tuple[float, float, float, float]], coating: str = "none") -> LensSystem:
    """A lens from rows (radius, thickness, index, aperture diameter), coated with ``coating``."""
    radius, thickness, index, aperture = (list(column) for column in zip(*rows))
    lens = build_lens("test.dat", list(range(1, len(rows) + 1)), radius, thickness, index, [0.0] * len(rows),
                      aperture)
    return lens.with_coating(coating)


def plate(thickness: float = 5.0, index: float = 1.6) -> LensSystem:
    """A stop, then a plane-parallel plate, bare."""
    return _lens([(0.0, 5.0, 1.0, 10.0), (math.inf, thickness, index, 20.0), (math.inf, 30.0, 1.0, 20.0)])


def collimated_bundle(lens: LensSystem, film_distance: float, radius: float, angle_deg: float = 0.0,
                across: int = 41) -> tuple[np.ndarray, np.ndarray]:
    """A square grid of parallel rays over a disk of ``radius`` about the front vertex's axis point,
    heading toward the film at ``angle_deg`` to the axis (toward -y), launched in front of the lens.
    The grid is mirror-symmetric in x bit for bit, as the lens is."""
    half = (across - 1) / 2
    g = (np.arange(across) - half) / half  # exactly symmetric about 0 (linspace's ends round apart)
    x, y = np.meshgrid(g, g)
    keep = x * x + y * y <= 1.0
    front = lens.vertex_z_mm(film_distance)[0]
    height = float(lens.aperture_mm.max())  # in front of any sag of the front surface
    a = math.radians(angle_deg)
    origins = np.column_stack([x[keep] * radius, y[keep] * radius + math.tan(a) * height,
                               np.full(keep.sum(), front + height)])
    return origins, np.broadcast_to([0.0, -math.sin(a), -math.cos(a)], origins.shape).copy()


# ------------------------------------------------------------------ enumeration

def test_ideal_coating_has_no_ghosts() -> None:
    assert ghost_paths(load_lens("dgauss")) == []
    assert ghost_paths(load_lens("dgauss").with_coating("ideal"), threshold=0.0) == []


def test_every_pair_of_reflecting_surfaces_is_listed_brightest_first() -> None:
    lens = load_lens("dgauss").with_coating("none")
    reflecting = np.flatnonzero(lens.interface_models != IDEAL)
    paths = ghost_paths(lens, threshold=0.0)
    assert {(p.first, p.second) for p in paths} == {(int(j), int(i)) for i in reflecting for j in reflecting if j < i}
    assert lens.stop not in {s for p in paths for s in (p.first, p.second)}
    throughput = [p.throughput for p in paths]
    assert throughput == sorted(throughput, reverse=True)
    assert ghost_paths(lens, threshold=1e-3) == [p for p in paths if p.throughput >= 1e-3]
    assert GhostPath(paths[0].first, paths[0].second) == paths[0]


def test_bad_paths_and_thresholds_are_user_errors() -> None:
    lens = plate()
    origins, directions = collimated_bundle(lens, 30.0, 1.0)
    for path in (GhostPath(2, 1), GhostPath(1, 1), GhostPath(0, 3), GhostPath(-1, 2)):
        with pytest.raises(UserError, match="first < second"):
            trace_ghost(lens, 30.0, path, origins, directions)
    for threshold in (-0.1, 1.5, math.nan):
        with pytest.raises(UserError, match="ghost threshold"):
            ghost_paths(lens, threshold=threshold)
    with pytest.raises(UserError, match="origins"):
        trace_direct(lens, 30.0, origins[:, :2], directions)


# ------------------------------------------------------------------ the plate

def test_plate_ghost_is_r1_r2_of_the_direct_image() -> None:
    """At normal incidence the plate's one ghost carries R1 R2 of the direct image's light, with
    R = ((n - 1) / (n + 1))^2 at each face (Fresnel), and ghost_paths' throughput is T1 R2 R1 T2."""
    n = 1.6
    lens = plate(index=n)
    r = ((n - 1) / (n + 1)) ** 2
    (ghost,) = ghost_paths(lens, wavelength_nm=WAVELENGTH, threshold=0.0)
    assert (ghost.first, ghost.second) == (1, 2)
    assert ghost.throughput == pytest.approx((1 - r) ** 2 * r * r, rel=1e-13)
    origins, directions = collimated_bundle(lens, 30.0, 4.0)
    direct = trace_direct(lens, 30.0, origins, directions, WAVELENGTH)
    traced = trace_ghost(lens, 30.0, ghost, origins, directions, WAVELENGTH)
    assert direct.passed.all() and traced.passed.all()
    np.testing.assert_allclose(traced.weight / direct.weight, r * r, rtol=1e-13)
    np.testing.assert_allclose(traced.film_xy, origins[:, :2], atol=1e-12)  # a plate does not bend axial light


def test_ghost_of_a_plate_behind_a_lens_focuses_2t_over_n_nearer() -> None:
    """Unfolded, the ghost crosses the plate three times instead of once: 2 t / n more reduced path,
    so its focus lies 2 t / n in front of the direct image's (paraxial imaging). The traced ghost's
    best focus (least mean squared spot of a narrow bundle) lands there."""
    t, n = 5.0, 1.6
    lens = _lens([(0.0, 2.0, 1.0, 4.0), (50.0, 4.0, 1.5, 20.0), (-50.0, 10.0, 1.0, 20.0),
                  (math.inf, t, n, 30.0), (math.inf, 30.0, 1.0, 30.0)])
    lens = lens.with_coating(("ideal", "ideal", "ideal", "none", "none"))
    bfl = paraxial_data(lens, WAVELENGTH).bfl_mm
    film = bfl  # film at the direct paraxial focus: z = 0
    origins, directions = collimated_bundle(lens, film, 0.3, across=21)

    def best_focus_z(trace: GhostTrace) -> float:
        assert trace.passed.all()
        slope = trace.direction[:, :2] / trace.direction[:, 2:3]
        return float(-np.sum(trace.film_xy * slope) / np.sum(slope * slope))

    assert best_focus_z(trace_direct(lens, film, origins, directions, WAVELENGTH)) == pytest.approx(0.0, abs=2e-3)
    (ghost,) = ghost_paths(lens, wavelength_nm=WAVELENGTH, threshold=0.0)
    ghost_z = best_focus_z(trace_ghost(lens, film, ghost, origins, directions, WAVELENGTH))
    assert ghost_z == pytest.approx(2 * t / n, abs=2e-3)
    # ``lens ghosts``'s focus, from the stop's whole 4 mm bundle: both foci move by the same spherical aberration
    direct_row, ghost_row = summarise(lens, film, [ghost], wavelength_nm=WAVELENGTH)
    assert ghost_row.focus_mm - direct_row.focus_mm == pytest.approx(2 * t / n, abs=1e-2)


# ------------------------------------------------------------------ energy

class _Budget:
    """Where the light of each ray of a bundle goes, followed branch by branch: at every interface
    the flux splits into the reflected R and the transmitted T (asserted R + T = 1); the branches are
    followed to the film up to two reflections. The leaves are the film (by the reflections taken),
    the scene (light reflected once, leaving the front), the lens barrel (a miss or a clear aperture),
    and the third reflections, not followed."""

    def __init__(self, lens: LensSystem, film_distance: float, origins: np.ndarray, directions: np.ndarray):
        self.lens = lens
        self.vertex_z = lens.vertex_z_mm(film_distance)
        behind = lens.index_at(WAVELENGTH)
        self.front, self.behind = np.concatenate([[1.0], behind[:-1]]), behind
        self.film: dict[tuple[int, ...], np.ndarray] = defaultdict(lambda: np.zeros(len(origins)))
        self.lost = {"scene": np.zeros(len(origins)), "barrel": np.zeros(len(origins)),
                     "third reflection": np.zeros(len(origins))}
        self.interfaces = 0
        o: Vectors = (origins[:, 0], origins[:, 1], origins[:, 2])
        d: Vectors = (directions[:, 0], directions[:, 1], directions[:, 2])
        self._follow(o, d, np.ones(len(origins)), 0, -1, True, ())

    def _follow(self, o: Vectors, d: Vectors, flux: np.ndarray, surface: int, previous: int, toward_film: bool,
                reflections: tuple[int, ...]) -> None:
        lens = self.lens
        if surface == lens.surface_count:  # past the rear surface: the film plane z = 0
            t = -o[2] / d[2]
            assert np.all(t[flux > 0] > 0)
            self.film[reflections] += flux
            return
        if surface < 0:
            self.lost["scene"] += flux
            return
        ahead = previous < 0 or lens.thickness_mm[min(previous, surface)] != 0
        o, normal, miss = intersect_surface(o, d, self.vertex_z[surface], lens.radius_mm[surface], ahead)
        clipped = miss | ~(o[0] ** 2 + o[1] ** 2 <= (lens.aperture_mm[surface] / 2) ** 2)
        self.lost["barrel"] += np.where(clipped, flux, 0.0)
        flux = np.where(clipped, 0.0, flux)
        n_from, n_to = ((self.front[surface], self.behind[surface]) if toward_film
                        else (self.behind[surface], self.front[surface]))
        cosine = incidence_cosine(d, normal)
        rs, rp, ts, tp = reflect_transmit(int(lens.interface_models[surface]), n_from, n_to, cosine, WAVELENGTH)
        r, t = 0.5 * (rs + rp), 0.5 * (ts + tp)
        np.testing.assert_allclose((r + t)[~clipped], 1.0, rtol=0, atol=1e-13)
        self.interfaces += 1
        step = 1 if toward_film else -1
        if n_from != n_to:
            transmitted, tir = refract(d, normal, n_from / n_to)
            assert np.all(t[tir] == 0)
        else:
            transmitted = d
        self._follow(o, transmitted, flux * t, surface + step, surface, toward_film, reflections)
        if lens.interface_models[surface] == IDEAL:
            return
        if len(reflections) == 2:
            self.lost["third reflection"] += flux * r
            return
        reflected = tuple(d[k] + 2 * cosine * normal[k] for k in range(3))
        self._follow(o, reflected, flux * r, surface - step, surface, not toward_film, (*reflections, surface))


@pytest.mark.parametrize("coating", ["none", "mgf2"])
@pytest.mark.parametrize("angle", [0.0, 12.0])
def test_direct_light_ghosts_and_lost_light_add_up_to_the_light_entering(coating: str, angle: float) -> None:
    """For a lossless stack (a cemented doublet and a stop), the light that trace_direct and
    trace_ghost bring to the film, plus the light the budget follows elsewhere (out of the front, into
    the barrel, into third reflections), is the light entering, per ray, to 1e-6. A missing Fresnel
    factor, a ghost counted twice or left out, or a clipped ray let through breaks the sum; the
    bundle overfills the lens so that clipping takes part."""
    lens = _lens([(40.0, 5.0, 1.6, 20.0), (-30.0, 2.0, 1.75, 20.0), (-90.0, 4.0, 1.0, 20.0),
                  (0.0, 40.0, 1.0, 12.0)], coating)
    film = 40.0
    origins, directions = collimated_bundle(lens, film, 13.0, angle, across=61)
    budget = _Budget(lens, film, origins, directions)
    assert budget.interfaces >= 15  # every branch up to two reflections
    assert budget.lost["barrel"].max() > 0.5 and budget.lost["scene"].max() > 0.01
    leaves = sum(budget.lost.values()) + sum(budget.film.values())
    np.testing.assert_allclose(leaves, 1.0, rtol=0, atol=1e-12)

    direct = trace_direct(lens, film, origins, directions, WAVELENGTH)
    ghosts = ghost_paths(lens, wavelength_nm=WAVELENGTH, threshold=0.0)
    assert len(ghosts) == 3
    traced = {(g.second, g.first): trace_ghost(lens, film, g, origins, directions, WAVELENGTH) for g in ghosts}
    on_film = direct.weight + sum(trace.weight for trace in traced.values())
    np.testing.assert_allclose(on_film + sum(budget.lost.values()), 1.0, rtol=0, atol=1e-6)
    np.testing.assert_allclose(direct.weight, budget.film[()], rtol=0, atol=1e-15)
    for key, trace in traced.items():
        np.testing.assert_allclose(trace.weight, budget.film[key], rtol=0, atol=1e-15)
    assert set(budget.film) - {()} <= set(traced)


# ------------------------------------------------------------------ symmetry

def _centroid(trace: GhostTrace) -> np.ndarray:
    w = trace.weight
    return np.sum(trace.film_xy[trace.passed] * w[trace.passed, None], axis=0) / w.sum()


def test_on_axis_ghosts_of_dgauss_are_centred_on_the_axis() -> None:
    lens = load_lens("dgauss").with_coating("none")
    film = paraxial_data(lens).bfl_mm
    origins, directions = collimated_bundle(lens, film, lens.aperture_mm[0] / 2)
    paths = ghost_paths(lens)
    assert len(paths) > 10
    for path in paths:
        trace = trace_ghost(lens, film, path, origins, directions)
        assert trace.passed.any(), path
        np.testing.assert_allclose(_centroid(trace), 0.0, atol=1e-9, err_msg=str(path))


def test_off_axis_ghosts_of_dgauss_lie_on_the_line_through_the_image_and_the_centre() -> None:
    """A light at 8 deg toward -y: its image lies on the film's y axis, and so does every ghost,
    some on the image's side and some (the point-symmetric ones) on the other."""
    lens = load_lens("dgauss").with_coating("none")
    film = paraxial_data(lens).bfl_mm
    origins, directions = collimated_bundle(lens, film, lens.aperture_mm[0] / 2, 8.0)
    image = _centroid(trace_direct(lens, film, origins, directions))
    assert abs(image[0]) < 1e-9 and abs(image[1]) > 3.0
    sides = []
    for path in ghost_paths(lens):
        trace = trace_ghost(lens, film, path, origins, directions)
        if trace.weight.sum() < 1e-3 * trace.passed.size * path.throughput:
            continue  # all but vignetted away
        centroid = _centroid(trace)
        assert abs(centroid[0]) < 1e-9 * max(1.0, abs(centroid[1])), path
        sides.append(np.sign(centroid[1]) == np.sign(image[1]))
    assert any(sides) and not all(sides)


def test_direct_path_steps_refract_at_every_surface() -> None:
    lens = plate()
    assert path_steps(lens, None) == [(0, False), (1, False), (2, False)]
    assert path_steps(lens, GhostPath(1, 2)) == [(0, False), (1, False), (2, True), (1, True), (2, False)]


# ------------------------------------------------------------------ the command

def test_lens_ghosts_lists_the_ghosts_above_the_threshold(capsys: pytest.CaptureFixture[str]) -> None:
    from realistic.cli import main

    assert main(["lens", "ghosts", "dgauss", "--threshold", "2e-3", "--field", "10"]) == 0
    lines = capsys.readouterr().out.splitlines()
    lens = load_lens("dgauss").with_coating("none")
    expected = ghost_paths(lens, threshold=2e-3)
    rows = [line.split() for line in lines if line.split()[1:2] == ["then"]]
    assert [(int(r[0]), int(r[2])) for r in rows] == [(p.second, p.first) for p in expected]
    assert [float(r[3]) for r in rows] == pytest.approx([p.throughput for p in expected], rel=1e-3)
    direct = next(line.split() for line in lines if line.split()[:1] == ["direct"])
    assert float(direct[-2]) < -5 and float(direct[-1]) == 1.0  # the image of a light at 10 deg lies toward -y
    glare = next(line for line in lines if line.startswith("veiling glare"))
    assert float(glare.split(" bring ")[1].split()[0]) == pytest.approx(sum(float(r[-1]) for r in rows), rel=2e-3)


@pytest.mark.parametrize(("flag", "value", "message"), [("--threshold", "2", "ghost threshold"),
                                                         ("--field", "95", "field angle"),
                                                         ("--coating", "ideal", "invalid choice"),
                                                         ("--focus", "-1", "focus distance")])
def test_lens_ghosts_refuses_bad_values_in_one_line(capsys: pytest.CaptureFixture[str], flag: str, value: str,
                                                    message: str) -> None:
    from realistic.cli import main

    assert main(["lens", "ghosts", "dgauss", flag, value]) == 2
    error = capsys.readouterr().err.strip().splitlines()
    assert len(error) == 1 and message in error[0]


def test_one_wavelength_per_ray_traces_as_each_wavelength_alone() -> None:
    lens = load_lens("dgauss").with_coating("mgf2")
    film = paraxial_data(lens).bfl_mm
    origins, directions = collimated_bundle(lens, film, lens.aperture_mm[0] / 2, 5.0, across=21)
    wavelengths = np.where(np.arange(len(origins)) % 2 == 0, 450.0, 650.0)
    path = ghost_paths(lens, threshold=0.0)[0]
    mixed = trace_ghost(lens, film, path, origins, directions, wavelengths)
    for wavelength in (450.0, 650.0):
        alone = trace_ghost(lens, film, path, origins, directions, wavelength)
        rows = wavelengths == wavelength
        np.testing.assert_array_equal(mixed.passed[rows], alone.passed[rows])
        np.testing.assert_allclose(mixed.weight[rows], alone.weight[rows], rtol=1e-14, atol=0)
        np.testing.assert_allclose(mixed.film_xy[rows], alone.film_xy[rows], rtol=1e-14, atol=1e-14)
    blue, red = (trace_ghost(lens, film, path, origins, directions, w).film_xy for w in (450.0, 650.0))
    assert np.nanmax(np.abs(blue - red)) > 1e-3  # dispersion moves the ghost
