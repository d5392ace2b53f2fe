"""Plots for benchmark reports (matplotlib, a dev dependency; never imported by the library)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from control.motion import Motion, forward_kinematics


def bic_curve(curve: dict, title: str, path: Path) -> None:
    """BIC (and effective BIC) against the number of clusters."""
    fig, ax = plt.subplots(figsize=(6, 3.5))
    ax.plot(curve["k"], curve["bic"], "o-", label="BIC, all frames (eq. 6)")
    ax.set_xlabel("clusters k")
    ax.set_ylabel("BIC")
    if curve.get("bic_effective") is not None:
        ax2 = ax.twinx()
        ax2.plot(
            curve["k"],
            curve["bic_effective"],
            "s--",
            color="C1",
            label=f"BIC, effective n (frames / {curve['decorrelation_frames']})",
        )
        ax2.set_ylabel("effective BIC")
        ax2.axvline(curve["chosen_k"], color="C1", lw=0.8)
        lines = ax.get_legend_handles_labels()[0] + ax2.get_legend_handles_labels()[0]
        labels = ax.get_legend_handles_labels()[1] + ax2.get_legend_handles_labels()[1]
        ax.legend(lines, labels, loc="lower right", fontsize=8)
    ax.axvline(25, color="grey", ls=":", lw=0.8)
    ax.set_title(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def pose_sheet(
    motions: Sequence[Motion], frames: Sequence[int], titles: Sequence[str], path: Path
) -> None:
    """A grid of stick figures seen from the front (x-y), one per (motion, frame)."""
    n = len(frames)
    cols = min(8, n)
    rows = (n + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(1.6 * cols, 2.2 * rows), squeeze=False)
    for ax in axes.ravel():
        ax.axis("off")
    for i, (m, f, title) in enumerate(zip(motions, frames, titles, strict=True)):
        ax = axes.ravel()[i]
        pos = forward_kinematics(m).positions[f]
        pos = pos - pos[0] * np.array([1.0, 0.0, 1.0])
        for j, p in enumerate(m.skeleton.parents):
            if p >= 0:
                ax.plot(pos[[p, j], 0], pos[[p, j], 1], "k-", lw=1.2)
        ax.set_xlim(-1.0, 1.0)
        ax.set_ylim(-0.1, 2.1)
        ax.set_aspect("equal")
        ax.set_title(title, fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
