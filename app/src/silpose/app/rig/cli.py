"""``silpose rig import`` and ``silpose rig show`` (a typer group; entry point ``rig`` in app/pyproject.toml).

Only light modules are imported here; numpy, OpenCV and matplotlib come with the commands.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, List, Optional

import typer

from silpose.shared.cli import fail

from .formats import format_choices, formats_summary

app = typer.Typer(
    name="rig",
    help="Camera rigs: import a calibration (formats: silpose rig import --help) as a rig file; show a rig.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


@app.command("import")
def import_command(
    calib: Annotated[List[Path], typer.Argument(help=f"Calibration file(s). {formats_summary()}.")],
    out: Annotated[Path, typer.Option("--out", "-o", help="The rig file to write (JSON).")],
    fmt: Annotated[str, typer.Option("--format", help=f"{format_choices()} (auto: by the file's name).")] = "auto",
    translation: Annotated[str, typer.Option(help="What the files' translations are: auto (world->camera, x_cam = R X "
                                                  "+ t, except Human3.6M-style JSON records, whose T is the camera "
                                                  "centre), world-to-camera, or camera-centre (x_cam = R (X - t)).")
                           ] = "auto",
    cameras: Annotated[Optional[str], typer.Option(help="Keep only these cameras: names or patterns separated by "
                                                        "commas (e.g. 00_* for CMU Panoptic's HD cameras).")] = None,
    unit: Annotated[Optional[str], typer.Option(help="The calibration's length unit: mm, cm, m, or metres per unit "
                                                     "(default m).")] = None,
    image_size: Annotated[Optional[str], typer.Option(help="WIDTHxHEIGHT for cameras whose file has no image size, "
                                                           "or per camera: cam1=1000x1002,1000x1000 (default: read an "
                                                           "image or video of the camera next to the file).")] = None,
    up: Annotated[str, typer.Option(help="The calibration axis pointing up: auto (the cameras' image up), +x, -x, +y, "
                                         "-y, +z or -z.")] = "auto",
    origin: Annotated[str, typer.Option(help="auto (the centre of the floor region the cameras see) or X,Y,Z in the "
                                             "calibration's units: its floor position becomes silpose's (0, 0).")] = "auto",
    floor_offset: Annotated[float, typer.Option(help="The floor's coordinate along up, calibration units (0: the "
                                                     "calibration board lay on the floor).")] = 0.0,
    workspace: Annotated[str, typer.Option(help="auto (the largest floor rectangle where a person is fully visible), "
                                                "WxH (metres, centred at the origin) or WxH@X,Y.")] = "auto",
    min_views: Annotated[Optional[int], typer.Option(min=1, help="Cameras that must see a person in the automatic "
                                                                 "workspace (default: all). With fewer than all, silpose "
                                                                 "gen places its walkers on the part every camera sees.")] = None,
    person_height: Annotated[float, typer.Option(help="Height (m) of the tallest person to keep in view.")] = 2.0,
    footprint: Annotated[float, typer.Option(help="Side (m) of the person's square footprint kept in view (0: a "
                                                  "vertical line at the walker's position).")] = 0.0,
    step: Annotated[float, typer.Option(help="Floor cell (m) of the automatic workspace.")] = 0.1,
    show: Annotated[Optional[Path], typer.Option(help="Also draw the rig (silpose rig show) into this PNG.")] = None,
) -> None:
    """Convert calibration files into a silpose rig file (z up, metres, floor z = 0, a workspace).

    Prints what it decided (unit, up axis, floor, origin, workspace, image sizes) so you can check it;
    the transform from the calibration's frame is stored in the rig file, so every output can also be
    given back in your own frame.
    """
    from silpose.shared.camera import RigError

    from .importer import ImportOptions, import_rig, write_rig
    from .show import describe_rig, draw_rig

    if not (0 <= footprint < 10 and 0.5 <= person_height <= 3.0 and 0.005 <= step <= 1.0):
        fail("rig import", "--footprint must be in [0, 10), --person-height in [0.5, 3], --step in [0.005, 1] metres")
    _claim_rig_outputs(calib, out, show)
    options = ImportOptions(fmt=fmt, translation=translation, cameras=cameras, unit=unit, up=up, origin=origin, floor_offset=floor_offset, image_size=image_size,
                            workspace=workspace, min_views=min_views, person_height=person_height,
                            footprint=footprint, step=step)
    try:
        result = import_rig(calib, options)
        written = write_rig(result.rig, out)
    except RigError as exc:
        fail("rig import", str(exc))
    except OSError as exc:
        fail("rig import", f"{out}: cannot write the rig file ({exc.strerror or exc})")
    for note in result.notes:
        print(f"- {note}")
    print(describe_rig(result.rig, str(written), height=person_height))
    print(f"wrote {written}")
    if show is not None:
        print(f"wrote {draw_rig(result.rig, show, height=person_height)}")


@app.command("show")
def show_command(
    rig: Annotated[Path, typer.Argument(help="A rig file (rig.json from `silpose rig import`).")],
    out: Annotated[Optional[Path], typer.Option("--out", "-o", help="Draw the rig into this PNG.")] = None,
    person_height: Annotated[float, typer.Option(help="Height (m) of the workspace box.")] = 2.0,
) -> None:
    """Print each camera in silpose's convention (centre, viewing direction, focal length, image size,
    distortion) and the workspace; with --out, draw a top view and every camera's image with the
    workspace box and a 1.75 m figure."""
    from silpose.shared.camera import Rig, RigError, load_rig

    from .show import describe_rig, draw_rig

    if out is not None:
        from silpose.shared.output_dir import claim_picture

        _claim("rig show", lambda: claim_picture(out, "rig show"))
    try:
        loaded = load_rig(rig)
        stored = Rig.from_json(rig.read_text(encoding="utf-8-sig")).source  # where it was imported from
    except RigError as exc:
        fail("rig show", str(exc))
    print(describe_rig(loaded, str(rig), height=person_height, imported_from=stored))
    if out is not None:
        try:
            print(f"wrote {draw_rig(loaded, out, height=person_height)}")
        except OSError as exc:
            fail("rig show", f"{out}: cannot write the picture ({exc.strerror or exc})")


def is_rig_file(path: Path) -> bool:
    """True if ``path`` holds a silpose rig (JSON that :meth:`Rig.from_json` accepts): a file ``rig import`` may replace."""
    from silpose.shared.camera import Rig, RigError

    try:
        Rig.from_json(path.read_text(encoding="utf-8-sig"))
    except (OSError, UnicodeDecodeError, ValueError, RigError):
        return False
    return True


def _claim(command: str, check) -> None:
    from silpose.shared.output_dir import OutputFolderError

    try:
        check()
    except OutputFolderError as exc:
        fail(command, str(exc))


def _claim_rig_outputs(calib: list[Path], out: Path, show: Optional[Path]) -> None:
    """Before any work: ``--out`` is not one of the calibration files and is new or a silpose rig file;
    ``--show`` is a new PNG or one silpose drew."""
    from silpose.shared.output_dir import claim_files, claim_picture

    inputs = {p.resolve() for p in calib if p.exists()}
    for given, flag in ((out, "--out"), (show, "--show")):
        if given is not None and given.resolve() in inputs:
            fail("rig import", f"{given}: {flag} names one of the calibration files being imported; choose another name")
    _claim("rig import", lambda: claim_files([out], "rig import", recognise=is_rig_file))
    if show is not None:
        _claim("rig import", lambda: claim_picture(show, "rig import"))
