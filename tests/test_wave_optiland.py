"""Our FFT MTF and Strehl ratio of the bundled double Gauss against optiland's (an independent optics package), at the
d line on the axis and at 15 deg; skipped unless optiland is installed (extra ``crosscheck``)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from realistic.optics.diffraction import pupil_function, strehl_ratio
from realistic.optics.formats import load_lens
from realistic.optics.mtf import lens_mtf
from realistic.optics.paraxial import paraxial_data
from realistic.optics.wavefront import wavefront

optic = pytest.importorskip("optiland.optic", reason="optiland is not installed (pip install .[crosscheck])")
materials = pytest.importorskip("optiland.materials")
mtf = pytest.importorskip("optiland.mtf")
psf = pytest.importorskip("optiland.psf")

ROOT = Path(__file__).resolve().parents[1]

FREQUENCIES = np.array([10.0, 30.0, 50.0, 100.0])


def _crosscheck_bench():
    """bench/crosscheck_optiland.py, whose ``optiland_system`` builds the prescription in optiland."""
    spec = importlib.util.spec_from_file_location("bench_crosscheck_optiland",
                                                  ROOT / "bench" / "crosscheck_optiland.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


BENCH = _crosscheck_bench()
D_UM, FIELDS, optiland_dgauss = BENCH.D_UM, BENCH.FIELDS, BENCH.optiland_system


def test_fft_mtf_of_dgauss_matches_optiland() -> None:
    lens = load_lens("dgauss")
    system = optiland_dgauss(lens)
    theirs = mtf.FFTMTF(system, fields="all", wavelength=D_UM, num_rays=256, grid_size=1024)
    ours = lens_mtf(lens, list(FIELDS), [D_UM * 1000], 100.0, samples_across=256, frequency_count=101)
    for k in range(len(FIELDS)):
        for curve, index, frequencies in ((ours.tangential[k], 0, theirs.freq_tang[k]),
                                          (ours.sagittal[k], 1, theirs.freq_sag[k])):
            expected = np.interp(FREQUENCIES, np.asarray(frequencies), np.asarray(theirs.mtf[k][index]))
            got = np.interp(FREQUENCIES, ours.frequencies_lp_mm, curve)
            # Both reference spheres differ (our centroid, their chief ray) and sample the pupil apart.
            np.testing.assert_allclose(got, expected, atol=0.015)


def test_strehl_of_dgauss_matches_optiland() -> None:
    lens = load_lens("dgauss")
    system = optiland_dgauss(lens)
    for k, field in enumerate(FIELDS):
        theirs = float(psf.FFTPSF(system, (0, k), D_UM, num_rays=256, grid_size=1024).strehl_ratio())
        front = wavefront(lens, field, D_UM * 1000, paraxial_data(lens).bfl_mm, 256)
        assert strehl_ratio(pupil_function(front.opd_waves)) == pytest.approx(theirs, rel=0.1)
