"""Tables the hosts pack for the kernels, each declared once: the kernel's ``#define``s and the host's
packing both come from one ``Table``, so no column offset is kept by hand in two languages.

A table is rows of one scalar type (float32, int32 or float64), each row its fields in order, a
field one or more scalars wide. ``Table.defines`` writes ``PREFIX_FIELD`` (the field's first
column), ``PREFIX_WIDTH`` (the row's width) and, for a table with a variable-length tail after its
fields, ``PREFIX_TAIL`` (where the tail starts); the host prepends them to the kernel source it
builds. ``Table.pack`` lays numpy columns out into rows through a structured dtype.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike


@dataclass(frozen=True)
class Table:
    """``prefix``'s rows of ``scalar``: ``fields`` (name, width) in order; ``tail``: the name of a
    variable-length part after them (``#define PREFIX_TAIL`` its start), if any."""

    prefix: str
    scalar: type[np.generic]
    fields: tuple[tuple[str, int], ...]
    tail: str | None = None

    @cached_property
    def dtype(self) -> np.dtype:
        """One row as a structured dtype (no padding: the fields' scalars back to back)."""
        return np.dtype([(name, self.scalar, (width,)) for name, width in self.fields])

    @property
    def width(self) -> int:
        """Scalars per row."""
        return sum(width for _, width in self.fields)

    def offset(self, name: str) -> int:
        """Column of field ``name``'s first scalar."""
        names = [field for field, _ in self.fields]
        return sum(width for _, width in self.fields[:names.index(name)])

    def defines(self) -> str:
        """The kernel's ``#define`` lines for this table."""
        lines = [f"#define {self.prefix}_WIDTH {self.width}"]
        lines += [f"#define {self.prefix}_{name.upper()} {self.offset(name)}" for name, _ in self.fields]
        if self.tail is not None:
            lines.append(f"#define {self.prefix}_{self.tail.upper()} {self.width}")
        return "\n".join(lines) + "\n"

    def pack(self, count: int, **columns: ArrayLike) -> np.ndarray:
        """(count, width) rows of ``scalar`` with each named field from ``columns`` (broadcast to
        (count, field width)); fields not given are zero. An unknown name is a ValueError."""
        unknown = set(columns) - {name for name, _ in self.fields}
        if unknown:
            raise ValueError(f"{self.prefix} has no field {', '.join(sorted(unknown))}")
        rows = np.zeros(count, self.dtype)
        for name, value in columns.items():
            width = self.dtype[name].shape[0]
            array = np.asarray(value)
            if width == 1 and array.ndim == 1:  # a (count,) column of a one-scalar field
                array = array[:, None]
            rows[name] = np.broadcast_to(array, (count, width))
        return rows.view(self.scalar).reshape(count, self.width)


def constant_defines(prefix: str, names: tuple[str, ...]) -> str:
    """``#define PREFIX_NAME i`` for each of ``names`` (an enumeration both sides share)."""
    return "".join(f"#define {prefix}_{name.upper()} {index}\n" for index, name in enumerate(names))
