"""Write ``heart.png`` beside this script: the aperture mask README's ``--aperture-mask`` example names.

A 64 x 64 8-bit grey image, white (open) inside the heart curve (x^2 + y^2 - 1)^3 <= x^2 y^3 and
black elsewhere, spanning the stop's square as ``optics/stop_shape.mask_stop`` reads it (row 0 at
+y). Run from anywhere: ``python examples/make_heart.py``.
"""

from pathlib import Path

import imageio.v3 as iio
import numpy as np

SIDE = 64


def heart(side: int = SIDE) -> np.ndarray:
    """The mask as (side, side) uint8 levels: 255 inside the heart curve, 0 outside."""
    centres = (np.arange(side) + 0.5) / side * 2.6 - 1.3  # pixel centres over [-1.3, 1.3]
    x = centres[None, :]
    y = -centres[:, None] + 0.1  # row 0 at the top (+y); shifted so the curve sits in the middle
    inside = (x * x + y * y - 1) ** 3 <= x * x * y ** 3
    return np.where(inside, 255, 0).astype(np.uint8)


if __name__ == "__main__":
    iio.imwrite(Path(__file__).with_name("heart.png"), heart())
