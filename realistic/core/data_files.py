"""Files the package needs beside its code (the OpenCL kernel, the default scene).

They live at the top of a checkout (``kernels/``, ``scenes/``); a wheel installs them under
``<prefix>/share/realistic/`` (setup.cfg ``data_files``).
"""

from __future__ import annotations

import site
import sys
from pathlib import Path

from realistic.errors import UserError


def data_file(relative: str) -> Path:
    """The path of ``relative`` (e.g. ``kernels/lens.cl``) in a checkout or an installation."""
    candidates = [Path(__file__).resolve().parents[2] / relative]
    for prefix in (sys.prefix, site.getuserbase()):
        candidates.append(Path(prefix) / "share" / "realistic" / relative)
    for path in candidates:
        if path.is_file():
            return path
    raise UserError(f"{relative} not found (looked in {', '.join(map(str, candidates))}); reinstall the package")
