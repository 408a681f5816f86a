"""Train vs test characters side by side as a picture (``characters.png``, embedded in the dataset card
next to "train vs test characters"; docs/conventions.md, "Evaluation protocol").

Two panels, "train" (left) and "test" (right), each a grid of up to :data:`N_PER_SPLIT` silhouettes.
Samples are picked deterministically per split (:func:`pick_characters`): among the first
:data:`SCAN_SAMPLES` samples, the first sample of each distinct character kind
(:func:`silpose.datagen.characters.character_kind`), kinds with a skirt, dress or coat first, then
trousers or a jacket, then the rest, in order of first appearance; filled up with the next unused
samples when there are fewer kinds. Each cell is the sample's mask in the view where it covers the
most pixels (the clothing least hidden by the body), cropped to its bounding box with a
:data:`MARGIN` margin and scaled to :data:`CELL_HEIGHT` px, labelled with its kind, sample id and
view. Written with matplotlib's Agg backend, atomically (``silpose.shared.atomic``).
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from silpose.shared.atomic import write_figure_atomic
from silpose.shared.dataset import iter_shards, list_shards

from .characters import character_kind

CHARACTERS_NAME = "characters.png"
#: Silhouettes per split (panel).
N_PER_SPLIT = 8
#: Samples of each split searched for distinct kinds (the first ones, in shard order).
SCAN_SAMPLES = 256
#: Margin around a mask's bounding box, as a fraction of the box height.
MARGIN = 0.06
#: Height of every cell in pixels (cropped masks are scaled to this height).
CELL_HEIGHT = 160
#: Width of every cell as a fraction of its height (wider crops are shrunk to fit).
CELL_ASPECT = 0.75


def _priority(kind: str) -> int:
    """0: a skirt, dress or coat; 1: trousers or a jacket; 2: anything else (hair only, nothing)."""
    if "skirt:" in kind or "coat:" in kind:
        return 0
    return 1 if ("trousers:" in kind or "jacket" in kind) else 2


def choose(kinds: np.ndarray, n: int = N_PER_SPLIT) -> np.ndarray:
    """(<= n,) indices into ``kinds`` (N,) strings: first sample of each distinct kind, by
    :func:`_priority` then first appearance, filled up with the next unused indices."""
    first: dict[str, int] = {}
    for i, k in enumerate(kinds):
        first.setdefault(str(k), i)
    picked = sorted(first.values(), key=lambda i: (_priority(str(kinds[i])), i))[:n]
    rest = [i for i in range(len(kinds)) if i not in set(picked)]
    return np.array(picked + rest[: n - len(picked)], dtype=np.int64)


def pick_characters(root: str | Path, split: str, n: int = N_PER_SPLIT) -> list[dict]:
    """Up to ``n`` picked samples of ``split``: dicts with ``sample_id`` (int), ``kind`` (str),
    ``view`` (camera name) and ``mask`` ((H, W) uint8 0/1, that view's mask)."""
    shards, seen = [], 0
    for _, shard in iter_shards(root, split, columns=["subject", "area"], with_masks=True):
        shards.append(shard)
        seen += len(shard)
        if seen >= SCAN_SAMPLES:
            break
    kinds = np.concatenate([character_kind(s.subject) for s in shards])[:SCAN_SAMPLES]
    where = [(s, i) for s in shards for i in range(len(s))][:SCAN_SAMPLES]
    out = []
    for j in choose(kinds, n):
        shard, i = where[j]
        k = int(np.argmax(shard.extra["area"][i]))
        out.append({"sample_id": int(shard.sample_id[i]), "kind": str(kinds[j]), "view": shard.rig.names[k],
                    "mask": shard.masks[i, k]})
    return out


def crop_cell(mask: np.ndarray, height: int = CELL_HEIGHT, aspect: float = CELL_ASPECT) -> np.ndarray:
    """(height, round(aspect*height)) uint8 0/1: ``mask`` (H, W) cropped to its bounding box plus
    :data:`MARGIN`, scaled to ``height`` (or less, if it would be wider than the cell) and centred."""
    width = int(round(aspect * height))
    cell = np.zeros((height, width), np.uint8)
    ys, xs = np.nonzero(mask)
    if len(ys) == 0:
        return cell
    y0, y1, x0, x1 = ys.min(), ys.max() + 1, xs.min(), xs.max() + 1
    pad = int(np.ceil(MARGIN * (y1 - y0)))
    box = np.pad(mask[y0:y1, x0:x1].astype(np.uint8), pad)
    s = min(height / box.shape[0], width / box.shape[1])
    h, w = max(1, int(round(box.shape[0] * s))), max(1, int(round(box.shape[1] * s)))
    scaled = cv2.resize(box * 255, (w, h), interpolation=cv2.INTER_AREA) >= 128
    top, left = (height - h) // 2, (width - w) // 2
    cell[top:top + h, left:left + w] = scaled
    return cell


def write_characters(root: str | Path, out: str | Path | None = None, n: int = N_PER_SPLIT) -> Path | None:
    """Write the train vs test sheet (default ``root/characters.png``) and return its path; when a split
    has no shards, write nothing, delete a stale sheet at ``out`` and return None."""
    root = Path(root)
    out = Path(out) if out is not None else root / CHARACTERS_NAME
    if not (list_shards(root, "train") and list_shards(root, "test")):
        out.unlink(missing_ok=True)
        return None
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    picks = {s: pick_characters(root, s, n) for s in ("train", "test")}
    cols = 4
    rows = max(1, -(-max(len(p) for p in picks.values()) // cols))
    fig = plt.figure(figsize=(2 * cols * 1.3 + 0.3, rows * 2.35 + 0.45), layout="constrained")
    panels = fig.subfigures(1, 2, wspace=0.02)
    for panel, (split, samples) in zip(panels, picks.items()):
        panel.set_facecolor("#f2f2f2" if split == "train" else "#e8f0fa")
        panel.suptitle(f"{split} characters", fontsize=11, fontweight="bold")
        axes = panel.subplots(rows, cols, squeeze=False)
        for ax in axes.ravel():
            ax.set_axis_off()
        for ax, p in zip(axes.ravel(), samples):
            ax.imshow(crop_cell(p["mask"]), cmap="gray_r", vmin=0, vmax=1.4, interpolation="nearest")
            ax.set_title(p["kind"].replace("+", "\n") + f"\n#{p['sample_id']} {p['view']}", fontsize=6.5)
    fig.suptitle(f"{root.name}: character kind, sample id and view of each silhouette (cropped, equal height)",
                 fontsize=8)
    return write_figure_atomic(fig, out, dpi=110)
