"""Our FFT PSF and MTF of the bundled double Gauss against optiland's (an independent optics package, the
``crosscheck`` extra), at the d line on the axis and at 15 deg, film at the paraxial focus:

    .venv/bin/python bench/crosscheck_optiland.py [--json bench/results/crosscheck_optiland.json]

PSF: Strehl ratio, the peak's offset from the PSF's energy centroid (each package refers its PSF
to its own point: ours the centroid of the ray landings, optiland's the chief ray), and the fraction
of the PSF's energy within 2, 5, 10 and 20 um of that centroid (both PSFs summed the same way over
their own FFT samples). MTF: tangential and sagittal at 10, 20, 40 and 80 lp/mm. Both sample the
pupil with 256 rays across and pad the FFT; the prescription is handed to optiland surface by
surface (d-line indices, our apertures). And the Huygens PSF's Strehl ratio (``lens psf --model huygens``),
both normalised as optiland does: by the peak of the aberration-free on-axis beam, per unit power entering
the pupil (128 rays across).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from realistic.optics.diffraction import fft_psf, huygens_psf, pupil_function, strehl_ratio  # noqa: E402
from realistic.optics.formats import load_lens  # noqa: E402
from realistic.optics.lens import LensSystem  # noqa: E402
from realistic.optics.mtf import lens_mtf  # noqa: E402
from realistic.optics.paraxial import paraxial_data  # noqa: E402
from realistic.optics.wavefront import wavefront  # noqa: E402

D_UM = 0.5875618
FIELDS = (0.0, 15.0)
FREQUENCIES = (10.0, 20.0, 40.0, 80.0)
RADII_UM = (2.0, 5.0, 10.0, 20.0)
PUPIL_SAMPLES = 256
FFT_SIZE = 1024
HUYGENS_SAMPLES = 128


def optiland_system(lens: LensSystem) -> object:
    """The prescription in optiland, film at our paraxial focus, d line only."""
    from optiland import materials, optic

    para = paraxial_data(lens)
    system = optic.Optic()
    system.add_surface(index=0, thickness=np.inf)
    for i in range(lens.surface_count):
        n = float(lens.index_d[i])
        radius = float(lens.radius_mm[i])
        thickness = float(lens.thickness_mm[i]) if i < lens.surface_count - 1 else para.bfl_mm
        extra = {} if i == lens.stop else {"aperture": float(lens.aperture_mm[i])}
        system.add_surface(index=i + 1, radius=radius if radius != 0 else np.inf, thickness=thickness,
                           material="air" if n == 1.0 else materials.IdealMaterial(n=n), is_stop=i == lens.stop,
                           **extra)
    system.add_surface(index=lens.surface_count + 1)
    system.set_aperture(aperture_type="EPD", value=para.entrance_pupil_diameter_mm)
    system.set_field_type("angle")
    for field in FIELDS:
        system.add_field(y=field)
    system.add_wavelength(value=D_UM, is_primary=True)
    return system


def psf_numbers(psf: np.ndarray, spacing_um: tuple[float, float]) -> dict[str, object]:
    """Peak offset from the array's centre (x, y um) and encircled energy about the energy centroid.
    ``psf`` rows run along y, columns along x; ``spacing_um`` (x, y)."""
    size = psf.shape[0]
    ys, xs = ((np.arange(size) - size // 2) * s for s in (spacing_um[1], spacing_um[0]))
    row, column = np.unravel_index(int(np.argmax(psf)), psf.shape)
    total = psf.sum()
    cy, cx = float((psf.sum(axis=1) * ys).sum() / total), float((psf.sum(axis=0) * xs).sum() / total)
    r = np.hypot(*np.meshgrid(xs - cx, ys - cy))
    return {"peak_um": [float(xs[column]), float(ys[row])], "centroid_um": [cx, cy],
            "encircled": {f"{radius:g}": float(psf[r <= radius].sum() / total) for radius in RADII_UM}}


def huygens_strehl(lens: LensSystem, film_mm: float) -> list[float]:
    """Per field, the Huygens PSF's peak (searched on a 0.25 um grid about the FFT PSF's, 41 x 41 points)
    over the aberration-free on-axis beam's peak at its centre, per unit power entering the pupil as
    optiland normalises (ours is per unit power reaching the film: times the fraction of the on-axis
    beam's pupil cells that pass at the field)."""
    peaks, cells = [], []
    for field in FIELDS:
        front = wavefront(lens, field, D_UM * 1000, film_mm, HUYGENS_SAMPLES)
        pupil = pupil_function(front.opd_waves)
        psf = fft_psf(pupil, 4 * pupil.shape[0])
        row, column = np.unravel_index(int(np.argmax(psf)), psf.shape)
        size = psf.shape[0]
        du = [D_UM * 1e-3 * L / (size * front.spacing_mm) for L in front.scale_mm]
        centre = np.array([(column - size // 2) * du[0], (row - size // 2) * du[1]])
        offsets = np.linspace(-5e-3, 5e-3, 41)
        grid = np.stack(np.meshgrid(offsets, offsets), axis=-1).reshape(-1, 2) + centre
        peaks.append(float(huygens_psf(front.opd_waves, front.sphere_mm, D_UM * 1000, grid).max()))
        cells.append(int(np.isfinite(front.opd_waves).sum()))
        if field == 0.0:
            ideal = np.where(np.isfinite(front.opd_waves), 0.0, np.nan)
            reference = float(huygens_psf(ideal, front.sphere_mm, D_UM * 1000, np.zeros((1, 2)))[0])
    return [peak / reference * count / cells[0] for peak, count in zip(peaks, cells)]


def ours(lens: LensSystem) -> dict[str, object]:
    film = paraxial_data(lens).bfl_mm
    result: dict[str, object] = {}
    report = lens_mtf(lens, list(FIELDS), [D_UM * 1000], max(FREQUENCIES), samples_across=PUPIL_SAMPLES,
                      frequency_count=161)
    huygens = huygens_strehl(lens, film)
    for k, field in enumerate(FIELDS):
        front = wavefront(lens, field, D_UM * 1000, film, PUPIL_SAMPLES)
        pupil = pupil_function(front.opd_waves)
        size = max(FFT_SIZE, 4 * pupil.shape[0])
        psf = fft_psf(pupil, size)  # rows along the pupil grid's rows (+y), columns along +x
        spacing = tuple(D_UM * L * 1000 / (size * front.spacing_mm * 1000) for L in front.scale_mm)
        result[f"{field:g}"] = {
            "strehl": strehl_ratio(pupil), "huygens_strehl": huygens[k], **psf_numbers(psf, spacing),
            "tangential": np.interp(FREQUENCIES, report.frequencies_lp_mm, report.tangential[k]).tolist(),
            "sagittal": np.interp(FREQUENCIES, report.frequencies_lp_mm, report.sagittal[k]).tolist()}
    return result


def theirs(lens: LensSystem) -> dict[str, object]:
    from optiland import mtf, psf

    system = optiland_system(lens)
    curves = mtf.FFTMTF(system, fields="all", wavelength=D_UM, num_rays=PUPIL_SAMPLES, grid_size=FFT_SIZE)
    result: dict[str, object] = {}
    for k, field in enumerate(FIELDS):
        spread = psf.FFTPSF(system, (0, k), D_UM, num_rays=PUPIL_SAMPLES, grid_size=FFT_SIZE)
        huygens = psf.HuygensPSF(system, (0, k), D_UM, num_rays=HUYGENS_SAMPLES, image_size=96, pixel_pitch=2.5e-4)
        image = np.asarray(spread.psf)[::-1]  # optiland's rows run along -y (image convention): ours along +y
        dx = float(D_UM * spread._get_working_FNO() / (FFT_SIZE / (PUPIL_SAMPLES - 1)))
        result[f"{field:g}"] = {
            "strehl": float(spread.strehl_ratio()), "huygens_strehl": float(huygens.strehl_ratio()),
            **psf_numbers(image, (dx, dx)),
            "tangential": np.interp(FREQUENCIES, np.asarray(curves.freq_tang[k]),
                                    np.asarray(curves.mtf[k][0])).tolist(),
            "sagittal": np.interp(FREQUENCIES, np.asarray(curves.freq_sag[k]), np.asarray(curves.mtf[k][1])).tolist()}
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", type=Path, default=ROOT / "bench" / "results" / "crosscheck_optiland.json")
    args = parser.parse_args()
    lens = load_lens("dgauss")
    both = {"realistic": ours(lens), "optiland": theirs(lens)}
    print(f"{lens.name} at f/{paraxial_data(lens).f_number:.3g}, d line, film at the paraxial focus")
    header = "field  package    Strehl  Huygens  peak-centroid |x|,y um  " + "  ".join(f"EE{r:g}um" for r in RADII_UM)
    print(header + "  " + "  ".join(f"T/S@{f:g}" for f in FREQUENCIES))
    for field in FIELDS:
        for name, numbers in both.items():
            row = numbers[f"{field:g}"]
            assert isinstance(row, dict)
            ee = "  ".join(f"{row['encircled'][f'{r:g}']:6.3f}" for r in RADII_UM)
            mtf = "  ".join(f"{t:.3f}/{s:.3f}" for t, s in zip(row["tangential"], row["sagittal"]))
            # from the energy centroid; |x|: the PSF is symmetric in x, and its peak may be either of a twin pair
            dx, dy = (p - c for p, c in zip(row["peak_um"], row["centroid_um"]))
            peak = f"{abs(dx):.2f},{dy:+.2f}"
            print(f"{field:5g}  {name:9s}  {row['strehl']:6.3f}  {row['huygens_strehl']:7.3f}  {peak:22s}  {ee}  {mtf}")
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps({"lens": lens.name, "wavelength_um": D_UM, "fields_deg": FIELDS,
                                     "frequencies_lp_mm": FREQUENCIES, "radii_um": RADII_UM, **both}, indent=1) + "\n")
    print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
