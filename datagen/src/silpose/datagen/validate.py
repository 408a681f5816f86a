"""Check a generated dataset folder and summarise it (``silpose validate DIR``).

Checks, per split and shard (streaming, one shard in memory at a time):

- schema, metadata and NaNs (``silpose.shared.dataset`` validates every file it reads);
- counts and sample ids against ``manifest.json`` (each id 0..n-1 exactly once), sha256 of every shard;
- masks are 0/1; stored ``contour_centroid`` / ``contour_scale`` equal the mean / RMS radius of the
  stored contour (docs/conventions.md, "Contours");
- joints project inside their silhouettes: the share of NON-terminal joints (``TERMINAL_JOINTS``
  excluded, their end caps may leave them ~2 px outside) whose projection, rounded to the nearest
  pixel, is foreground — must be >= ``MIN_JOINTS_INSIDE``;
- contours lie on the mask boundary: distance of every contour point to the nearest boundary pixel
  centre (a foreground pixel with a 4-neighbour in the background), from an exact Euclidean distance
  transform sampled bilinearly — the maximum must be <= ``MAX_CONTOUR_OFF_BOUNDARY_PX``.

Reports per view: mean silhouette height (bounding box rows, px), mean contour length (px) and mean
area (px).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from silpose.shared.dataset import DatasetError, iter_shards, list_shards
from silpose.shared.dataset_schema import FORMAT_VERSION
from silpose.shared.skeleton import N_JOINTS, TERMINAL_JOINTS

from .manifest import MANIFEST, read_manifest, sha256_file

MIN_JOINTS_INSIDE = 0.99
#: Resampled points lie on segments between boundary-pixel centres (<= 1/sqrt(2) px away from one).
MAX_CONTOUR_OFF_BOUNDARY_PX = 1.0
NORMALISATION_TOL_PX = 1e-2


@dataclass
class ValidationReport:
    root: Path
    problems: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    splits: dict[str, dict] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return not self.problems

    def format(self) -> str:
        """A readable multi-line report."""
        lines = [f"dataset {self.root}"]
        for split, s in self.splits.items():
            lines.append(f"\n[{split}] {s['samples']} samples in {s['shards']} shard(s), {s['redraws']} redraws")
            lines.append(
                f"  joints inside silhouettes: non-terminal {100 * s['joints_inside']:.2f} %"
                f" (min {100 * MIN_JOINTS_INSIDE:.0f} %), terminal {100 * s['terminal_inside']:.2f} %"
            )
            lines.append(
                f"  contour to mask boundary: mean {s['contour_dist_mean']:.3f} px, max {s['contour_dist_max']:.3f} px"
                f" (max allowed {MAX_CONTOUR_OFF_BOUNDARY_PX} px)"
            )
            lines.append(f"  touching the border: {s['touches_border']} view-samples; several blobs: {s['multi_blob']}")
            lines.append("  view      height px   contour length px   area px")
            for v in s["views"]:
                lines.append(f"  {v['name']:<8} {v['height']:>10.1f} {v['contour_length']:>19.1f} {v['area']:>9.1f}")
        for n in self.notes:
            lines.append(f"note: {n}")
        lines.append("")
        if self.problems:
            lines.append(f"FAILED: {len(self.problems)} problem(s)")
            lines.extend(f"  - {p}" for p in self.problems)
        else:
            lines.append("OK: no problems found")
        return "\n".join(lines)


def _boundary(mask: np.ndarray) -> np.ndarray:
    """(H, W) bool: foreground pixels with a 4-neighbour in the background (or the image edge)."""
    m = np.pad(mask.astype(bool), 1)
    inner = m[1:-1, 1:-1]
    all_fg = m[:-2, 1:-1] & m[2:, 1:-1] & m[1:-1, :-2] & m[1:-1, 2:]
    return inner & ~all_fg


def _bilinear(img: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Sample (H, W) ``img`` at (n, 2) pixel coordinates (x, y), clamped to the image."""
    h, w = img.shape
    x = np.clip(pts[:, 0], 0, w - 1)
    y = np.clip(pts[:, 1], 0, h - 1)
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    x1, y1 = np.minimum(x0 + 1, w - 1), np.minimum(y0 + 1, h - 1)
    fx, fy = x - x0, y - y0
    return (img[y0, x0] * (1 - fx) * (1 - fy) + img[y0, x1] * fx * (1 - fy)
            + img[y1, x0] * (1 - fx) * fy + img[y1, x1] * fx * fy)


def contour_boundary_distance(mask: np.ndarray, contour: np.ndarray) -> np.ndarray:
    """(n,) distance in px of each contour point (n, 2) to the nearest boundary pixel centre of ``mask``."""
    b = _boundary(mask)
    if not b.any():
        return np.full(len(contour), np.inf)
    dist = cv2.distanceTransform((~b).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    return _bilinear(dist, np.asarray(contour, np.float64))


def joints_inside(masks: np.ndarray, pixels: np.ndarray) -> np.ndarray:
    """(N, K, J) bool: pixel (N, K, J, 2) rounded to the nearest pixel is foreground in masks (N, K, H, W)."""
    n, k, h, w = masks.shape
    xi = np.rint(pixels[..., 0]).astype(np.int64)
    yi = np.rint(pixels[..., 1]).astype(np.int64)
    inside = (xi >= 0) & (xi < w) & (yi >= 0) & (yi < h)
    xi, yi = np.clip(xi, 0, w - 1), np.clip(yi, 0, h - 1)
    ni = np.arange(n)[:, None, None]
    ki = np.arange(k)[None, :, None]
    return inside & (masks[ni, ki, yi, xi] > 0)


def validate_dataset(root: str | Path) -> ValidationReport:
    """Run every check on the dataset folder ``root`` (see the module docstring)."""
    root = Path(root)
    report = ValidationReport(root)
    if not root.is_dir():
        report.problems.append(f"{root}: dataset folder not found")
        return report
    manifest = None
    try:
        manifest = read_manifest(root)
    except (FileNotFoundError, ValueError) as exc:
        report.problems.append(str(exc))
    hashes = {s["file"]: s["sha256"] for s in manifest.get("shards", [])} if manifest else {}
    counts = dict(manifest.get("counts", {})) if manifest else {}
    splits = list(counts) or sorted({p.name.split("-")[0] for p in root.glob("*-of-*.parquet")})
    if not splits:
        report.problems.append(f"{root}: no shards found")
    for split in splits:
        try:
            if not list_shards(root, split) and counts.get(split, 0) == 0:
                continue
            _validate_split(root, split, counts.get(split), hashes, report, sha256_file)
        except DatasetError as exc:
            report.problems.append(str(exc))
    if manifest:
        for f in sorted(set(hashes) - {p.name for p in root.glob("*.parquet")}):
            report.problems.append(f"{root / f}: listed in {MANIFEST} but missing")
    return report


def _validate_split(root, split, expected, hashes, report, sha256_file) -> None:
    nonterm = np.array([j not in TERMINAL_JOINTS for j in range(N_JOINTS)])
    ids, n_shards, redraws = [], 0, 0
    inside_nt = inside_t = total_nt = total_t = 0
    dist_sum, dist_n, dist_max = 0.0, 0, 0.0
    touches = multi = 0
    height_sum = length_sum = area_sum = None
    names = None
    for path, s in iter_shards(root, split, with_masks=True):
        n_shards += 1
        names = s.rig.names
        version = s.metadata["format_version"]
        if path.name in hashes and sha256_file(path) != hashes[path.name]:
            report.problems.append(f"{path}: sha256 differs from manifest.json")
        elif hashes and path.name not in hashes:
            report.problems.append(f"{path}: not listed in manifest.json")
        ids.append(s.sample_id)
        redraws += int(s.extra["redraws"].sum())
        masks = s.masks
        if masks.max(initial=0) > 1:
            report.problems.append(f"{path}: column 'masks' has values other than 0/1")
        # normalisation factors equal the mean / RMS radius of the stored contour (docs/conventions.md, "Contours")
        c = s.contours.astype(np.float64).mean(axis=2)
        r = np.sqrt(((s.contours - c[:, :, None]) ** 2).sum(-1).mean(-1))
        if np.abs(c - s.centroid).max() > NORMALISATION_TOL_PX or np.abs(r - s.scale).max() > NORMALISATION_TOL_PX:
            report.problems.append(f"{path}: columns 'contour_centroid'/'contour_scale' disagree with 'contours'")
        px = np.moveaxis(s.rig.project(s.joints.astype(np.float64)), 0, 1)  # (N, K, 19, 2)
        ins = joints_inside(masks, px)
        inside_nt += int(ins[..., nonterm].sum())
        total_nt += int(ins[..., nonterm].size)
        inside_t += int(ins[..., ~nonterm].sum())
        total_t += int(ins[..., ~nonterm].size)
        for i in range(len(s)):
            for k in range(s.n_views):
                d = contour_boundary_distance(masks[i, k], s.contours[i, k])
                dist_sum += float(d.sum())
                dist_n += d.size
                dist_max = max(dist_max, float(d.max()))
        touches += int(s.touches_border.sum())
        multi += int((s.extra["n_blobs"] > 1).sum())
        rows_any = masks.any(axis=3)  # (N, K, H)
        first = rows_any.argmax(axis=2)
        last = masks.shape[2] - 1 - rows_any[:, :, ::-1].argmax(axis=2)
        heights = np.where(rows_any.any(axis=2), last - first + 1, 0).sum(0)
        lengths, areas = s.extra["contour_length"].astype(np.float64).sum(0), s.extra["area"].astype(np.float64).sum(0)
        height_sum = heights if height_sum is None else height_sum + heights
        length_sum = lengths if length_sum is None else length_sum + lengths
        area_sum = areas if area_sum is None else area_sum + areas
    if version != FORMAT_VERSION:
        report.notes.append(
            f"{root}: split {split!r} is in dataset format version {version}: silpose reads it, Hugging Face "
            f"datasets cannot; regenerate it for version {FORMAT_VERSION} with `silpose gen` (a run into the "
            "same folder rewrites the old shards)"
        )
    all_ids = np.sort(np.concatenate(ids))
    n = len(all_ids)
    if expected is not None and n != expected:
        report.problems.append(f"{root}: split {split!r} has {n} samples, manifest.json says {expected}")
    if not np.array_equal(all_ids, np.arange(n)):
        report.problems.append(f"{root}: split {split!r} column 'sample_id' is not 0..{n - 1}, each once")
    frac_nt = inside_nt / max(total_nt, 1)
    if frac_nt < MIN_JOINTS_INSIDE:
        report.problems.append(
            f"{root}: split {split!r}: only {100 * frac_nt:.2f} % of non-terminal joints project inside their "
            f"silhouettes (need {100 * MIN_JOINTS_INSIDE:.0f} %)"
        )
    if dist_max > MAX_CONTOUR_OFF_BOUNDARY_PX:
        report.problems.append(
            f"{root}: split {split!r} column 'contours': a point lies {dist_max:.2f} px from the mask boundary "
            f"(max {MAX_CONTOUR_OFF_BOUNDARY_PX} px)"
        )
    report.splits[split] = {
        "samples": n, "shards": n_shards, "redraws": redraws,
        "joints_inside": frac_nt, "terminal_inside": inside_t / max(total_t, 1),
        "contour_dist_mean": dist_sum / max(dist_n, 1), "contour_dist_max": dist_max,
        "touches_border": touches, "multi_blob": multi,
        "views": [
            {"name": names[k], "height": height_sum[k] / n, "contour_length": length_sum[k] / n, "area": area_sum[k] / n}
            for k in range(len(names))
        ],
    }
