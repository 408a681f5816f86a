"""Where a model's training data came from: the facts a model file records about its dataset.

:func:`manifest_sha256` digests a dataset folder's ``manifest.json``; ``ShapeStructureModel.fit_dataset``
and ``silpose train`` store it (with the folder and the generator config) in ``dataset_info_``,
which :mod:`silpose.model.persistence` writes into the model file. :func:`check_split_hashes` makes
sure the shards a model is trained on are the ones the manifest hashed (as ``silpose validate`` does).
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

from silpose.shared.dataset import DatasetError, list_shards


def file_sha256(path: str | Path) -> str:
    """Hex sha256 of a file's bytes (read in 1 MiB blocks)."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def manifest_sha256(root: str | Path) -> str | None:
    """sha256 of ``<root>/manifest.json``, or None when the dataset folder has no manifest."""
    manifest = Path(root) / "manifest.json"
    return file_sha256(manifest) if manifest.is_file() else None


def check_split_hashes(root: str | Path, split: str) -> int:
    """Check ``split``'s shards in ``root`` against the sha256 values of ``root/manifest.json``.

    A dataset without a manifest, or with one that lists no shards, is not checked (returns 0).
    Otherwise every shard of the split on disk must be listed with its sha256 and match it, and every
    listed shard of the split must exist; a shard edited after generation (even only its footer,
    which the page checksums do not cover) raises :class:`~silpose.shared.dataset.DatasetError`
    naming the file. Returns the number of shards checked.
    """
    root = Path(root)
    path = root / "manifest.json"
    if not path.is_file():
        return 0
    try:
        manifest = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise DatasetError(f"{path}: not valid JSON ({exc})") from None
    listed = manifest.get("shards") if isinstance(manifest, dict) else None
    if not isinstance(listed, list) or not listed:
        return 0
    hashes = {s.get("file"): s.get("sha256") for s in listed if isinstance(s, dict) and s.get("split") == split}
    shards = list_shards(root, split)
    for shard in shards:
        if shard.name not in hashes:
            raise DatasetError(f"{shard}: not listed in {path} (a shard of another run?); regenerate the dataset")
        if file_sha256(shard) != hashes[shard.name]:
            raise DatasetError(f"{shard}: sha256 differs from {path}: the shard was modified after generation; "
                               "regenerate it (silpose gen) or check it with silpose validate")
    missing = sorted(set(hashes) - {p.name for p in shards})
    if missing:
        raise DatasetError(f"{root / missing[0]}: listed in {path} but missing")
    return len(shards)
