"""Drawing convergence (matplotlib): RMSE against samples per pixel and against seconds."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from realistic.core.atomic_files import save_figure
from realistic.errors import UserError


def plot_convergence(rows: list[dict], out: Path, title: str) -> None:
    """Log-log RMSE against spp and against seconds, with a 1/sqrt(spp) guide."""
    import matplotlib
    import matplotlib.ticker

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    shown = [r for r in rows if r["rmse"] > 0]
    if not shown:
        raise UserError("nothing to plot: every render equals the reference")
    fig, (by_spp, by_time) = plt.subplots(1, 2, figsize=(10, 4))
    spp = np.array([r["spp"] for r in shown], dtype=float)
    error = np.array([r["rmse"] for r in shown])
    by_spp.loglog(spp, error, "o-", label="RMSE")
    by_spp.loglog(spp, error[0] * np.sqrt(spp[0] / spp), "--", color="grey", label="1/sqrt(spp)")
    by_spp.set_xlabel("samples per pixel")
    by_spp.set_ylabel("RMSE")
    by_spp.legend()
    by_time.loglog([r["seconds"] for r in shown], error, "o-")
    by_time.set_xlabel("seconds")
    for ax in (by_spp, by_time):
        ax.grid(True, which="both", alpha=0.3)
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())  # decade labels only
    fig.suptitle(title)
    fig.tight_layout()
    save_figure(fig, out, 120)
    plt.close(fig)
