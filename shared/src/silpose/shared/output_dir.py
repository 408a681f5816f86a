"""Output folders are silpose's alone: the one check every writing command runs before it writes.

Two kinds of output (docs/conventions.md, "Crash safety"):

- **Folders** (``gen``, ``gen-frames``, ``eval``, ``infer --overlays``): a command writes only
  into a folder that is new, empty, or recognisably its own output: it holds the marker
  :data:`MARKER` naming the command (written by :func:`claim_folder` before anything else), or
  the caller's ``recognise`` function knows an output written before markers existed (a dataset's
  ``manifest.json``, a frames dataset's identity file, an evaluation's ``headline.json``). A
  folder marked by another command is refused too. :func:`check_folder` runs the same test
  without writing (for ``gen-frames``, which builds its folder elsewhere and renames it).
- **Named files** (``train``: the model and its reports; ``infer``: the joints, contours and
  segmentation files): these may go into any folder, next to the user's files, but a command
  creates new files or replaces only files that ``recognise`` says silpose wrote
  (:func:`claim_files`); it never deletes anything else.

Paths that resolve to the working folder or one of its parents (``.``, ``..``), to the silpose
repository or one of its parents, or to the data root or one of its parents are never output
folders (:func:`check_output_path`). There is no ``--force``: a new or empty folder is always a way
out, and forcing would bring back exactly the losses this module prevents (a user's README.md
replaced by a dataset card, ``.*.tmp`` files deleted by a resuming run).

Errors are :class:`OutputFolderError`, one line naming the folder and the files silpose did not write.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path

from .atomic import FIGURE_SOFTWARE, write_json_atomic

__all__ = [
    "MARKER",
    "MARKER_FORMAT",
    "OutputFolderError",
    "repository_root",
    "check_output_path",
    "read_marker",
    "check_folder",
    "claim_folder",
    "claimed_folder",
    "claim_files",
    "is_silpose_png",
    "claim_picture",
]

#: The file silpose writes into every output folder it owns: ``{"written_by": "silpose", "command": ...}``.
MARKER = ".silpose-output.json"
MARKER_FORMAT = 1
#: Foreign file names shown in an error message at most.
SHOWN = 5

Recogniser = Callable[[Path], bool]


class OutputFolderError(ValueError):
    """An output folder or file that silpose must not write; the message names it and the foreign files."""


def repository_root() -> Path | None:
    """The silpose repository (the folder holding ``uv.lock`` and ``pyproject.toml`` above this
    module; also found from a ``.venv`` inside it), or None when silpose is installed elsewhere."""
    for parent in Path(__file__).resolve().parents:
        if (parent / "uv.lock").is_file() and (parent / "pyproject.toml").is_file():
            return parent
    return None


def _is_same_or_parent(path: Path, of: Path) -> bool:
    return path == of or path in of.parents


def check_output_path(path: str | Path, *, data_root: str | Path | None = None) -> Path:
    """Raise :class:`OutputFolderError` if the folder ``path`` resolves to the working folder, the
    silpose repository, the data root (default ``data``) or a parent of any of them; else return it.

    ``path`` may not exist yet; symbolic links are resolved.
    """
    path = Path(path)
    resolved = path.expanduser().resolve()
    guarded = [(Path.cwd().resolve(), "the working folder")]
    repo = repository_root()
    if repo is not None:
        guarded.append((repo, "the silpose repository"))
    data = Path("data" if data_root is None else data_root).expanduser().resolve()
    guarded.append((data, "the data root"))
    for protected, what in guarded:
        if _is_same_or_parent(resolved, protected):
            relation = "is" if resolved == protected else "is a parent of"
            raise OutputFolderError(
                f"{path}: resolves to {resolved}, which {relation} {what} ({protected}); "
                "give a folder of its own (e.g. a new subfolder)"
            )
    return path


def read_marker(folder: str | Path) -> dict | None:
    """The marker of ``folder`` as a dict, or None when it has none (or an unreadable one)."""
    try:
        marker = json.loads((Path(folder) / MARKER).read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(marker, dict) or marker.get("written_by") != "silpose":
        return None
    return marker


def _foreign_text(names: list[str]) -> str:
    shown = ", ".join(names[:SHOWN])
    return shown + (f" and {len(names) - SHOWN} more" if len(names) > SHOWN else "")


def check_folder(folder: str | Path, command: str, *, recognise: Recogniser | None = None,
                 data_root: str | Path | None = None) -> str:
    """Raise :class:`OutputFolderError` unless ``command`` may write into ``folder``; writes nothing.

    Returns how the folder qualifies: ``"new"`` (absent), ``"empty"``, ``"marked"`` (its marker names
    ``command``) or ``"recognised"`` (``recognise(folder)`` is true: an output of ``command``
    written before markers existed).
    """
    folder = check_output_path(folder, data_root=data_root)
    if not folder.exists():
        return "new"
    if not folder.is_dir():
        raise OutputFolderError(f"{folder}: exists and is not a folder")
    entries = sorted(p.name for p in folder.iterdir())
    if not entries:
        return "empty"
    marker = read_marker(folder)
    if marker is not None:
        owner = marker.get("command")
        if owner == command:
            return "marked"
        raise OutputFolderError(
            f"{folder}: holds the output of 'silpose {owner}', not of 'silpose {command}'; choose a new or empty folder"
        )
    if recognise is not None and recognise(folder):
        return "recognised"
    raise OutputFolderError(
        f"{folder}: not an output folder of 'silpose {command}' and not empty; silpose did not write "
        f"{_foreign_text(entries)}; choose a new or empty folder (nothing was written)"
    )


def claim_folder(folder: str | Path, command: str, *, recognise: Recogniser | None = None,
                 data_root: str | Path | None = None) -> Path:
    """Check ``folder`` (:func:`check_folder`), create it if needed and mark it as ``command``'s
    output (the marker is written before any other file). Returns the folder."""
    folder = Path(folder)
    state = check_folder(folder, command, recognise=recognise, data_root=data_root)
    if state != "marked":
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise OutputFolderError(f"{folder}: cannot create the output folder ({exc.strerror or exc})") from None
        write_json_atomic(folder / MARKER, {"written_by": "silpose", "command": command, "format": MARKER_FORMAT})
    return folder


@contextmanager
def claimed_folder(folder: str | Path, command: str, *, recognise: Recogniser | None = None,
                   data_root: str | Path | None = None) -> Iterator[Path]:
    """:func:`claim_folder` for the length of a ``with`` block: when the block raises, a folder this claim
    created, or a marker it added, is removed again if nothing else was written, so a refused command leaves
    nothing behind."""
    folder = Path(folder)
    existed, marked = folder.exists(), (folder / MARKER).exists()
    claim_folder(folder, command, recognise=recognise, data_root=data_root)
    try:
        yield folder
    except BaseException:
        try:
            if not marked and [p.name for p in folder.iterdir()] == [MARKER]:
                (folder / MARKER).unlink()
                if not existed:
                    folder.rmdir()
        except OSError:
            pass  # cleaning up must not hide the error being raised
        raise


def claim_files(paths: Iterable[str | Path], command: str, *, recognise: Recogniser) -> list[Path]:
    """Raise :class:`OutputFolderError` unless every path in ``paths`` is new or, when it exists, a
    file that ``recognise(path)`` says silpose wrote; writes nothing. Returns the paths.

    For commands writing named files next to the user's own (``train``, ``infer``).
    """
    paths = [Path(p) for p in paths]
    foreign: list[Path] = []
    for p in paths:
        if p.is_dir():
            raise OutputFolderError(f"{p}: is a folder; 'silpose {command}' writes a file here (give a file name)")
        if p.exists() and not recognise(p):
            foreign.append(p)
    if foreign:
        raise OutputFolderError(
            f"{foreign[0].parent}: 'silpose {command}' would replace {_foreign_text([p.name for p in foreign])}, "
            "which silpose did not write; choose another --out or move the file (nothing was written)"
        )
    return paths


_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def is_silpose_png(path: str | Path) -> bool:
    """True if ``path`` is a PNG whose ``Software`` text chunk says silpose wrote it
    (``silpose.shared.atomic.write_figure_atomic``). Reads the chunks before the image data only."""
    try:
        with open(path, "rb") as f:
            if f.read(8) != _PNG_SIGNATURE:
                return False
            while True:
                head = f.read(8)
                if len(head) < 8:
                    return False
                length, kind = int.from_bytes(head[:4], "big"), head[4:]
                if kind in (b"IDAT", b"IEND") or length > 1 << 20:
                    return False
                data = f.read(length)
                f.read(4)  # CRC
                if kind == b"tEXt":
                    key, _, value = data.partition(b"\0")
                    if key == b"Software" and value.decode("latin-1").startswith(FIGURE_SOFTWARE):
                        return True
    except OSError:
        return False


def claim_picture(path: str | Path, command: str) -> Path:
    """Check a picture path given with ``--out``: new, or a PNG silpose wrote (:func:`is_silpose_png`);
    it must end in ``.png``. Raises :class:`OutputFolderError` (one line); writes nothing."""
    path = Path(path)
    if path.suffix.lower() != ".png":
        raise OutputFolderError(f"{path}: 'silpose {command}' writes a PNG picture; give a file name ending in .png")
    return claim_files([path], command, recognise=is_silpose_png)[0]
