"""Shared figure helpers: every figure is saved the same way, atomically."""
from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from workflows.io import atomic_path  # noqa: E402


def save_figure(fig, path: str, dpi: int = 130) -> None:
    """Tight layout, write PNG atomically to ``path``, close the figure."""
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=dpi, format="png")
    plt.close(fig)
