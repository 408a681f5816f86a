"""Box plots in the paper's style (Figs. 5 and 8): median line, quartile box, dashed whiskers to the
most extreme point within 1.5 IQR of the box, outliers beyond them marked '+'.

Files are written atomically (:func:`silpose.shared.atomic.write_figure_atomic`). matplotlib runs headless
(Agg) and is imported on first use (:func:`pyplot`), not with this module.
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from silpose.shared.atomic import write_figure_atomic

from .experiments import E1_PER_VIEW
from .report import e1_comparison
from .tables import select

__all__ = ["pyplot", "paper_boxplot", "save_figure", "plot_e1", "plot_e2", "plot_e3", "plot_e4"]


def pyplot():
    """``matplotlib.pyplot`` with the headless Agg backend (matplotlib is imported here, lazily)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def paper_boxplot(ax, data: Sequence[np.ndarray], labels: Sequence[str], ylabel: str, title: str = "") -> None:
    """Draw one paper-style box plot: each entry of ``data`` (finite values used) is one box."""
    clean = [np.asarray(d, np.float64)[np.isfinite(np.asarray(d, np.float64))] for d in data]
    clean = [d if len(d) else np.array([np.nan]) for d in clean]
    ax.boxplot(
        clean,
        whis=1.5,
        widths=0.5,
        medianprops={"color": "red", "linewidth": 1.5},
        boxprops={"color": "blue"},
        whiskerprops={"color": "black", "linestyle": "--"},
        capprops={"color": "black"},
        flierprops={"marker": "+", "markeredgecolor": "red", "markersize": 5, "linestyle": "none"},
        showfliers=True,
    )
    ax.set_xticks(np.arange(1, len(labels) + 1), labels)
    ax.set_ylabel(ylabel)
    if title:
        ax.set_title(title)
    ax.grid(axis="y", alpha=0.3)


def save_figure(fig, path: str | Path, dpi: int = 110) -> Path:
    """Save ``fig`` as PNG atomically (temporary file, then rename), cropped to its content; closes the figure."""
    return write_figure_atomic(fig, path, dpi=dpi, tight=True)


def plot_e1(df, path) -> Path | None:
    """E1: pose (left) and contour (right) error distributions, single- vs multi-view training."""
    e1 = select(df, experiment="E1")
    if e1.empty:
        return None
    c = e1_comparison(df)
    pv = c.get("equal_q_per_view")
    labels = ["single-view\ntraining\n(equal q)"] + (["single-view\ntraining\n(q / K)"] if pv else []) + ["multi-view\ntraining"]
    pose = [select(e1, training="single-view")["pose_cm"]] + ([select(e1, training=E1_PER_VIEW)["pose_cm"]] if pv else [])
    chamfer = [c["_sv_chamfer"]] + ([pv["_sv_chamfer"]] if pv else [])
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(9 if pv else 8, 4))
    paper_boxplot(axes[0], pose + [select(e1, training="multi-view")["pose_cm"]], labels, "pose error (cm)", "Pose")
    paper_boxplot(axes[1], chamfer + [c["_mv_chamfer"]], labels, "Chamfer distance true→recon (px)", "Contours")
    fig.suptitle("E1: training on single vs multiple views (cf. paper Fig. 5)")
    return save_figure(fig, path)


def plot_e2(df, path) -> Path | None:
    """E2: pose and contour errors for 4, 3, 2, 1 input views with the 4-view model."""
    e2 = select(df, experiment="E2")
    if e2.empty:
        return None
    ns = sorted(e2["n_input_views"].unique(), reverse=True)
    labels = [f"{n} view{'s' if n > 1 else ''}" for n in ns]
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(9, 4))
    paper_boxplot(axes[0], [select(e2, n_input_views=n)["pose_cm"] for n in ns], labels, "pose error (cm)", "Pose")
    paper_boxplot(axes[1], [select(e2, n_input_views=n)["chamfer_px"] for n in ns], labels,
                  "Chamfer distance true→recon (px)", "Contours (all 4 views)")
    fig.suptitle("E2: 4-view model given a subset of views (cf. paper Fig. 8)")
    return save_figure(fig, path)


def plot_e3(df, path) -> Path | None:
    """E3: pose error per noise setting (4-view model, all views; and the first other input subset)."""
    e3 = select(df, experiment="E3", method="mppca")
    if e3.empty:
        return None
    subsets = list(dict.fromkeys(e3["input_views"]))
    noises = list(dict.fromkeys(e3["noise"]))
    plt = pyplot()
    fig, axes = plt.subplots(len(subsets), 1, figsize=(max(8, 0.8 * len(noises)), 3.2 * len(subsets)), squeeze=False)
    for ax, views in zip(axes[:, 0], subsets):
        paper_boxplot(ax, [select(e3, input_views=views, noise=nz)["pose_cm"] for nz in noises], noises,
                      "pose error (cm)", f"E3: noise sweep, input views {views}")
        ax.tick_params(axis="x", labelrotation=30)
    fig.tight_layout()
    return save_figure(fig, path)


def plot_e4(df, path) -> Path | None:
    """E4: pose error of MPPCA, kNN, ridge and MLP per number of input views, plus chance."""
    e4 = select(df, experiment="E4")
    e2 = select(df, experiment="E2")
    if e4.empty:
        return None
    data, labels = [], []
    for n in sorted(e4["n_input_views"].unique(), reverse=True):
        if n == 0:
            continue
        if not e2.empty:
            data.append(select(e2, n_input_views=n)["pose_cm"])
            labels.append(f"MPPCA\n{n}v")
        for m in ("knn", "ridge", "mlp"):
            g = select(e4, n_input_views=n, method=m)
            if len(g):
                data.append(g["pose_cm"])
                labels.append(f"{m}\n{n}v")
    data.append(select(e4, method="chance")["pose_cm"])
    labels.append("chance")
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(max(8, 0.7 * len(labels)), 4))
    paper_boxplot(ax, data, labels, "pose error (cm)", "E4: MPPCA vs kNN vs ridge vs MLP vs chance")
    return save_figure(fig, path)
