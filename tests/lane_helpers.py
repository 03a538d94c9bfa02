"""The shading kernel's shadow rays in lanes (``packet_loop.LANE_DEFINES``), converted to and from
point-major rows (hit i's k-th ray at row i per + k) by the tests, independently of ``packet_loop``'s
own ``shadow_lanes`` and ``lane_rows``."""

import numpy as np

from realistic.scene.packet_loop import PACKET


def point_major(lanes: np.ndarray) -> np.ndarray:
    """A launch's output in lanes ((hits / 16, per, width, 16), or a length's (hits / 16, per, 16)) as
    point-major rows: (rows, width), or (rows,)."""
    if lanes.ndim == 3:
        return lanes.transpose(0, 2, 1).reshape(-1)
    return lanes.transpose(0, 3, 1, 2).reshape(-1, lanes.shape[2])


def in_lanes(rows: np.ndarray, per: int) -> np.ndarray:
    """Point-major rows ((hits per, width) or (hits per,)) in lanes, the hits padded with zero rows
    to a multiple of 16: ``point_major``'s inverse."""
    width = rows.shape[1] if rows.ndim == 2 else 1
    hits = len(rows) // per
    padded = np.zeros((-(-hits // PACKET) * PACKET, per, width), rows.dtype)
    padded[:hits] = rows.reshape(hits, per, width)
    lanes = np.ascontiguousarray(padded.reshape(-1, PACKET, per, width).transpose(0, 2, 3, 1))
    return lanes if rows.ndim == 2 else lanes[:, :, 0]
