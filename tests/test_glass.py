"""Glass catalogues: the makers' data sheets, the formats that name glasses, and the tracer and
kernel using a catalogue glass's formula; flat refracting faces read as planes in every format."""

import dataclasses
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from kernel_reference import assert_kernel_matches, camera_for_lens
from realistic import load_lens
from realistic.camera.base import SampleBlock
from realistic.errors import LensFileError, UserError
from realistic.optics.dispersion import LAMBDA_C_UM, LAMBDA_D_UM, LAMBDA_F_UM
from realistic.optics.formats import format_lens, parse_text
from realistic.optics.formats.codev import parse_codev
from realistic.optics.formats.json_lens import parse_json_lens
from realistic.optics.formats.pbrt_dat import parse_prescription
from realistic.optics.formats.zemax import parse_zmx
from realistic.optics.forward_trace import reversed_lens
from realistic.optics.glass.catalogue import find_glass
from realistic.optics.paraxial import paraxial_data
from realistic.optics.report import format_summary, lens_summary
from realistic.optics.tracer import trace_from_film

REPO = Path(__file__).resolve().parents[1]

# (glass, catalogue, n_C, n_d, n_F, V_d) as each maker's data sheet prints them (indices to 1e-5, V_d to 0.01)
DATA_SHEETS = [
    ("N-BK7", "schott", 1.51432, 1.51680, 1.52238, 64.17),  # SCHOTT data sheet N-BK7
    ("S-LAH58", "ohara", 1.87656, 1.88300, 1.89822, 40.76),  # OHARA catalogue S-LAH58
    ("FCD1", "hoya", 1.49514, 1.49700, 1.50123, 81.61),  # HOYA data table FCD1
    ("H-FK61", "cdgm", 1.49513, 1.49700, 1.50123, 81.61),  # CDGM catalogue H-FK61
]


@pytest.mark.parametrize(("name", "catalogue", "n_c", "n_d", "n_f", "abbe"), DATA_SHEETS)
def test_catalogue_formula_matches_the_data_sheet(name, catalogue, n_c, n_d, n_f, abbe):
    glass = find_glass(name, catalogue)
    assert glass is not None
    n = glass.index(np.array([LAMBDA_C_UM, LAMBDA_D_UM, LAMBDA_F_UM]))
    np.testing.assert_allclose(n, [n_c, n_d, n_f], rtol=0, atol=1e-5)
    # the sheet rounds V_d to 0.01; its indices' rounding (5e-6) moves V_d by up to V 2e-5 / (n_F - n_C)
    assert abs(glass.abbe_v - abbe) <= 0.005 + abbe * 2e-5 / (n_f - n_c)


def test_names_match_without_case_spaces_or_hyphens():
    assert find_glass("n-bk7") == find_glass("NBK7") == find_glass("N-BK7", "schott")
    assert find_glass("S-BSL7", "ohara") is not None  # the sheet writes "S-BSL 7"
    assert find_glass("N-BK7", "ohara") is None


ZMX_SINGLET = """VERS 190513 80 123
MODE SEQ
UNIT MM X W X CM MR CPMM
GCAT SCHOTT OHARA
SURF 0
  TYPE STANDARD
  CURV 0.0
  DISZ INFINITY
SURF 1
  STOP
  TYPE STANDARD
  CURV 0.0
  DISZ 5
  DIAM 8 0 0 0 1 ""
SURF 2
  TYPE STANDARD
  CURV 0.02
  DISZ 6
  GLAS {glass} 0 0 1.5168 64.17 0 0 0 0 0 0
  DIAM 12.5 0 0 0 1 ""
  MEMA 13 0 0 0 1 ""
  FLAP 0 12.5 0
SURF 3
  TYPE STANDARD
  CURV -0.005
  DISZ 90
  MEMA 12.5 0 0 0 1 ""
SURF 4
  TYPE STANDARD
  CURV 0.0
  DISZ 0
  DIAM 20
"""


def test_zemax_catalogue_glass_gives_the_formula_at_every_wavelength():
    lens = parse_zmx(ZMX_SINGLET.format(glass="N-BK7"), "singlet.zmx")
    glass = find_glass("N-BK7")
    assert lens.glass[1] == glass and lens.glass[0] is None and lens.glass[2] is None
    assert lens.index_d[1] == glass.n_d and lens.has_dispersion
    for wavelength_um in (0.4047, LAMBDA_F_UM, LAMBDA_C_UM, 0.7065):
        assert lens.index_at(wavelength_um * 1000.0)[1] == pytest.approx(float(glass.index(wavelength_um)), abs=1e-15)
    assert lens.aperture_mm[2] == 25.0  # MEMA stands in for the missing DIAM (SURF 3)
    # the catalogue formula, not Cauchy from n_d and V_d: they differ by 1e-4 at the h line
    cauchy = dataclasses.replace(lens, glass=(None,) * 3).index_at(404.7)[1]
    assert abs(lens.index_at(404.7)[1] - cauchy) > 5e-5


def test_zemax_unknown_glass_names_the_line_and_the_closest_names():
    with pytest.raises(LensFileError) as err:
        parse_zmx(ZMX_SINGLET.format(glass="N-BK77"), "singlet.zmx")
    message = str(err.value)
    assert "singlet.zmx" in message and ":19" in message and "N-BK77" in message and "N-BK7" in message
    assert "\n" not in message


# (PARAXIAL is traced now: tests/test_paraxial_surface.py)
@pytest.mark.parametrize(("kind", "line"), [("COORDBRK", "coordinate breaks")])
def test_zemax_refuses_what_real_rays_cannot_trace_with_file_and_line(kind, line):
    text = ZMX_SINGLET.format(glass="N-BK7").replace("SURF 3\n  TYPE STANDARD", f"SURF 3\n  TYPE {kind}")
    with pytest.raises(LensFileError, match=rf"singlet.zmx:24: TYPE {kind}: {line}"):
        parse_zmx(text, "singlet.zmx")


def test_zemax_without_gcat_finds_glasses_in_any_catalogue():
    lens = parse_zmx(ZMX_SINGLET.format(glass="S-LAH58").replace("GCAT SCHOTT OHARA\n", ""), "s.zmx")
    assert lens.glass[1] is not None and lens.glass[1].catalogue == "Ohara"


def test_codev_catalogue_names():
    text = ("RDM\nDIM M\nSO 0 1e20\nS 0 5\n  STO\n  CIR 8\nS 50 6 {glass}\n  CIR 12.5\n"
            "S -200 90\n  CIR 12.5\nSI 0 0\nGO\n")
    for name, catalogue in (("NBK7_SCHOTT", "Schott"), ("SLAH58_OHARA", "Ohara"), ("HK9L_CDGM", "CDGM"),
                            ("FCD1", "Hoya")):
        glass = parse_codev(text.format(glass=name), "lens.seq").glass[1]
        assert glass is not None and glass.catalogue == catalogue
    with pytest.raises(LensFileError, match=r"lens.seq:7: glass 'NBK77_SCHOTT'.*closest"):
        parse_codev(text.format(glass="NBK77_SCHOTT"), "lens.seq")


def test_json_glass_key_and_round_trips_keep_the_glass():
    text = """{"surfaces": [
 {"radius": 0, "thickness": 5, "ior": 0, "semi_aperture": 8},
 {"radius": 50, "thickness": 6, "ior": 0, "glass": "N-BK7 (Schott)", "semi_aperture": 12.5},
 {"radius": -200, "thickness": 90, "ior": 0, "semi_aperture": 12.5}]}"""
    lens = parse_json_lens(text, "lens.json")
    assert lens.glass[1] == find_glass("N-BK7")
    for suffix in (".json", ".zmx", ".seq"):
        again = parse_zmx(format_lens(lens, suffix)) if suffix == ".zmx" else parse_text(
            format_lens(lens, suffix), "again" + suffix, suffix)
        assert again.glass == lens.glass, suffix
        np.testing.assert_array_equal(again.index_d, lens.index_d)
    with pytest.raises(LensFileError, match=r"lens.json:3: glass 'N-BK77'"):
        parse_json_lens(text.replace("N-BK7 (Schott)", "N-BK77"), "lens.json")


# ------------------------------------------------------------------ flat refracting faces

R_MM, N_D = 50.0, 1.5168
PLANO_CONVEX_DAT = f"""# radius thickness n_d aperture
{R_MM} 5.0 {N_D} 20
0 3.0 0 20
0 40.0 0 10
"""
PLANO_CONVEX_JSON = f"""{{"surfaces": [
 {{"radius": {R_MM}, "thickness": 5.0, "ior": {N_D}, "semi_aperture": 10}},
 {{"radius": 0, "thickness": 3.0, "ior": 0, "semi_aperture": 10}},
 {{"radius": 0, "thickness": 40.0, "ior": 0, "semi_aperture": 5}}]}}"""


@pytest.mark.parametrize("lens", [parse_prescription(PLANO_CONVEX_DAT, "pc.dat"),
                                  parse_json_lens(PLANO_CONVEX_JSON, "pc.json")], ids=["dat", "json"])
def test_radius_zero_between_different_media_is_a_flat_face(lens):
    assert lens.stop == 2 and np.isinf(lens.radius_mm[1])
    # lensmaker's equation for a plano-convex lens: 1/f = (n - 1) / R, whatever the thickness
    assert paraxial_data(lens).efl_mm == pytest.approx(R_MM / (N_D - 1.0), rel=1e-12)
    # a real ray near the axis from infinity (traced backwards: from the focus) agrees to third order
    film = paraxial_data(lens).bfl_mm
    h = 1e-3
    hit = trace_from_film(lens, film, np.zeros((1, 3)), np.array([[h, 0.0, film]]))
    assert hit.passed.all()
    height = hit.origin[0, 0] + (hit.direction[0, 0] / hit.direction[0, 2]) * (0 - hit.origin[0, 2])
    assert height / (h / film) == pytest.approx(R_MM / (N_D - 1.0), rel=1e-5)


def test_a_flat_face_is_met_on_its_plane_exactly():
    lens = parse_prescription(PLANO_CONVEX_DAT, "pc.dat")
    film = paraxial_data(lens).bfl_mm
    path: list[np.ndarray] = []
    directions = np.array([[x, 0.0, film] for x in (0.5, 1.5, 2.5)])
    assert trace_from_film(lens, film, np.zeros((3, 3)), directions, path=path).passed.all()
    vertex = lens.vertex_z_mm(film)
    np.testing.assert_array_equal(path[1][:, 2], vertex[1])  # rear first: the stop, then the flat face


def test_kernel_traces_flat_faces_as_the_reference_does(opencl_platform):
    lens = parse_prescription(PLANO_CONVEX_DAT, "pc.dat")
    camera = dataclasses.replace(camera_for_lens(lens), lens_sampling="rear")
    count, seed = camera.sample_count, 5
    kernel = opencl_platform.LensKernel(camera).generate(SampleBlock(0, count, camera.spp), seed)
    ref = camera.generate_rays(SampleBlock(0, count, camera.spp), seed)
    assert assert_kernel_matches(kernel, ref, camera, seed).mean() > 0.02


def test_spectral_kernel_uses_the_catalogue_formula(opencl_platform):
    dgauss = load_lens("dgauss")
    glass = tuple(None if n == 1 else find_glass("N-SK16" if n < 1.65 else "N-SF5") for n in dgauss.index_d)
    lens = dataclasses.replace(dgauss, glass=glass,
                               index_d=np.array([1.0 if g is None else g.n_d for g in glass]),
                               abbe_v=np.array([0.0 if g is None else g.abbe_v for g in glass]))
    camera = camera_for_lens(lens, spectral=True)
    count, seed = camera.sample_count, 7
    kernel = opencl_platform.LensKernel(camera).generate(SampleBlock(0, count, camera.spp), seed)
    ref = camera.generate_rays(SampleBlock(0, count, camera.spp), seed)
    assert assert_kernel_matches(kernel, ref, camera, seed).mean() > 0.3


# ------------------------------------------------------------------ zero-thickness gaps

def test_zemax_stop_on_the_lens_vertex_is_a_zero_gap():
    touching = parse_zmx(ZMX_SINGLET.format(glass="N-BK7").replace("DISZ 5\n", "DISZ 0\n"), "touching.zmx")
    apart = parse_zmx(ZMX_SINGLET.format(glass="N-BK7"), "apart.zmx")
    assert touching.thickness_mm[0] == 0 and touching.stop == 0
    # the stop's place changes the pupils, never the focal length
    assert paraxial_data(touching).efl_mm == pytest.approx(paraxial_data(apart).efl_mm, rel=1e-14)
    film = paraxial_data(touching).bfl_mm
    directions = np.array([[x, 0.0, film] for x in (0.0, 1.0, 2.0)])
    assert trace_from_film(touching, film, np.zeros((3, 3)), directions).passed.all()


def test_zero_gap_where_the_surfaces_would_cross_is_refused_at_its_line():
    # R = +40 bulges toward the scene, so a stop 0 mm behind its vertex would cut through it
    with pytest.raises(LensFileError, match=r"b.dat:2: thickness 0 mm: .* cross inside their clear apertures"):
        parse_prescription("20 3 1.5 10\n40 0 0 10\n0 30 0 8\n", "b.dat")
    assert parse_prescription("20 3 1.5 10\n-40 0 0 10\n0 30 0 8\n", "b.dat").stop == 2


def test_kernel_traces_zero_gaps_as_the_reference_does(opencl_platform):
    lens = parse_zmx(ZMX_SINGLET.format(glass="N-BK7").replace("DISZ 5\n", "DISZ 0\n"), "touching.zmx")
    camera = dataclasses.replace(camera_for_lens(lens), lens_sampling="rear")
    count, seed = camera.sample_count, 3
    kernel = opencl_platform.LensKernel(camera).generate(SampleBlock(0, count, camera.spp), seed)
    ref = camera.generate_rays(SampleBlock(0, count, camera.spp), seed)
    assert assert_kernel_matches(kernel, ref, camera, seed).mean() > 0.02


# ------------------------------------------------------------------ a curved stop

ZMX_STOP_ON_LENS = """VERS 190513 80 123
MODE SEQ
UNIT MM X W X CM MR CPMM
SURF 0
  TYPE STANDARD
  CURV 0.0
  DISZ INFINITY
SURF 1
  STOP
  TYPE STANDARD
  CURV 0.02
  DISZ 6
  GLAS N-BK7 0 0 1.5168 64.17 0 0 0 0 0 0
  DIAM 8
SURF 2
  TYPE STANDARD
  CURV -0.005
  DISZ 90
  DIAM 12.5
SURF 3
  TYPE STANDARD
  CURV 0.0
  DISZ 0
  DIAM 20
"""


def test_zemax_curved_stop_on_a_lens_face_refracts_and_stops():
    lens = parse_zmx(ZMX_STOP_ON_LENS, "singlet.zmx")
    assert lens.stop == 0 and lens.radius_mm[0] == 50.0 and not lens.stop_is_flat_in_air
    # thick-lens focal length of the singlet: the stop surface refracts as any other
    n, r1, r2, t = find_glass("N-BK7").n_d, 50.0, -200.0, 6.0
    power = (n - 1) * (1 / r1 - 1 / r2 + (n - 1) * t / (n * r1 * r2))
    assert paraxial_data(lens).efl_mm == pytest.approx(1 / power, rel=1e-12)
    # the stop's clear semi-diameter (8 mm) is met on the curved face: a fan from the film centre
    # passes where it meets that face inside 8 mm and is stopped there (reason "stop") outside
    film = paraxial_data(lens).bfl_mm
    aims = np.array([[h, 0.0, film] for h in np.linspace(0.0, 12.0, 121)])
    paths: list[np.ndarray] = []
    traced = trace_from_film(lens, film, np.zeros((121, 3)), aims, path=paths)
    height = np.hypot(paths[-1][:, 0], paths[-1][:, 1])  # hits on surface 0 (the path runs rear first)
    stopped = (traced.blocked_reason == 3) & (traced.blocked_surface == 0)
    assert traced.passed.any() and stopped.any() and (traced.passed | stopped).all()
    assert np.all(height[traced.passed] <= 8.0) and np.all(height[stopped] > 8.0)
    np.testing.assert_allclose(paths[-1][:, 2], lens.vertex_z_mm(film)[0] - 50.0 + np.sqrt(2500.0 - height**2))


def test_curved_stop_round_trips_through_formats_that_mark_the_stop():
    lens = parse_zmx(ZMX_STOP_ON_LENS, "singlet.zmx")
    for suffix in (".zmx", ".seq"):
        text = format_lens(lens, suffix)
        again = parse_zmx(text) if suffix == ".zmx" else parse_text(text, "a.seq", suffix)
        assert again.stop == 0 and again.radius_mm[0] == 50.0 and again.glass == lens.glass, suffix
    for suffix in (".dat", ".json"):
        with pytest.raises(UserError, match="stop is curved"):
            format_lens(lens, suffix)


def test_kernel_traces_a_curved_stop_as_the_reference_does(opencl_platform):
    lens = parse_zmx(ZMX_STOP_ON_LENS, "singlet.zmx").with_stop_diameter(12.0)
    camera = dataclasses.replace(camera_for_lens(lens, spectral=True), lens_sampling="rear")
    count, seed = camera.sample_count, 9
    kernel = opencl_platform.LensKernel(camera).generate(SampleBlock(0, count, camera.spp), seed)
    ref = camera.generate_rays(SampleBlock(0, count, camera.spp), seed)
    assert assert_kernel_matches(kernel, ref, camera, seed).mean() > 0.02


def test_lens_info_names_catalogue_glasses_and_a_curved_stop():
    summary = lens_summary(parse_zmx(ZMX_STOP_ON_LENS, "singlet.zmx"))
    assert summary["surfaces"][0]["glass"] == "N-BK7 (Schott)" and "glass" not in summary["surfaces"][1]
    text = format_summary(summary)
    assert "50.0000*" in text and "N-BK7 (Schott)" in text and "the aperture stop, on a curved surface" in text


@pytest.mark.skipif(shutil.which("objdump") is None, reason="needs objdump")
@pytest.mark.parametrize(("crown", "flint"), [("N-SK16", "N-SF5"), ("FCD1", "E-FD1")], ids=["sellmeier", "schott"])
def test_spectral_kernel_with_catalogue_glasses_still_vectorises(opencl_platform, tmp_path, crown, flint):
    """Written as three like terms, Sellmeier's sum was packed into a vector by LLVM's SLP
    vectoriser and the whole kernel ran scalar (0 ymm instructions, a sixth of the speed)."""
    script = ("import dataclasses\nimport numpy as np\nfrom realistic import load_lens\n"
              "from realistic.camera.lens_camera import LensCamera\nfrom realistic.camera.base import SampleBlock\n"
              "from realistic.camera.opencl_host import LensKernel\n"
              "from realistic.optics.glass.catalogue import find_glass\n"
              "d = load_lens('dgauss100')\n"
              f"glass = tuple(None if n == 1 else find_glass({crown!r} if n < 1.65 else {flint!r})\n"
              "              for n in d.index_d)\n"
              "lens = dataclasses.replace(d, glass=glass)\n"
              "camera = LensCamera(lens, 75.0, 43.27, 64, 48, spp=4, spectral=True, wavelengths_per_sample=3)\n"
              "LensKernel(camera, rays_per_item=1).generate(SampleBlock(0, 4096, camera.spp), 0)\n")
    env = {**os.environ, "XDG_CACHE_HOME": str(tmp_path), "REALISTIC_CACHE_DIR": "off",
           "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")])}
    subprocess.run([sys.executable, "-c", script], check=True, env=env, cwd=REPO, timeout=120)
    (so,) = tmp_path.glob("pocl/kcache/**/generate_rays/**/*.so")
    code = subprocess.run(["objdump", "-d", str(so)], capture_output=True, text=True, check=True).stdout
    assert code.count("%ymm") + code.count("%zmm") > 500, "the work-group loop is not vectorised"
    assert "call" not in code, "a builtin call stops PoCL's vectoriser"


@pytest.mark.parametrize("wavelength_um", [LAMBDA_F_UM, LAMBDA_D_UM, LAMBDA_C_UM])
def test_focal_length_at_each_line_follows_the_catalogue_index(wavelength_um):
    lens = parse_zmx(ZMX_STOP_ON_LENS, "singlet.zmx")
    n, r1, r2, t = float(find_glass("N-BK7").index(wavelength_um)), 50.0, -200.0, 6.0
    power = (n - 1) * (1 / r1 - 1 / r2 + (n - 1) * t / (n * r1 * r2))
    assert paraxial_data(lens, wavelength_um * 1000.0).efl_mm == pytest.approx(1 / power, rel=1e-12)
    # seen from the film (spot and MTF trace the reversed lens), the glass moves with its medium
    back = reversed_lens(lens)
    assert back.glass == (lens.glass[0], None) and back.index_d[0] == lens.index_d[0]
    assert paraxial_data(back, wavelength_um * 1000.0).efl_mm == pytest.approx(1 / power, rel=1e-12)
