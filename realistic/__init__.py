"""realistic: a physically based renderer whose camera is a real multi-element lens."""

from realistic.errors import LensFileError, UserError
from realistic.prescription import BUNDLED_LENSES, LensSystem, load_lens, parse_prescription

__all__ = ["BUNDLED_LENSES", "LensFileError", "LensSystem", "UserError", "load_lens", "parse_prescription"]
__version__ = "0.1.0"
