"""Where a model's training data came from: the facts a model file records about its dataset.

:func:`manifest_sha256` digests a dataset folder's ``manifest.json``; ``ShapeStructureModel.fit_dataset``
and ``silpose train`` store it (with the folder and the generator config) in ``dataset_info_``,
which :mod:`silpose.model.persistence` writes into the model file.
"""

from __future__ import annotations

import hashlib
from pathlib import Path


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
