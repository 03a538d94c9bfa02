"""The package's version, in the lowest layer so that what writes it into files (the EXR header's
``software``) needs no import of the package itself."""

__version__ = "0.1.0"
