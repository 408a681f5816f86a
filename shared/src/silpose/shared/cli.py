"""The one ``silpose`` command, composed from the installed packages.

Each package declares its subcommands as entry points in the group ``silpose.commands``
(name = subcommand, value = a plain function with typer-annotated parameters, or a ``typer.Typer``
holding a group of subcommands, e.g. ``silpose rig import`` / ``silpose rig show``). Loading them
imports only the packages' light ``cli`` modules: heavy work (bpy, sklearn) is imported inside
the commands, so ``silpose --help`` stays fast and never touches Blender.
"""

from __future__ import annotations

import sys
from contextlib import contextmanager
from importlib.metadata import entry_points

import typer

from .version import silpose_version

ENTRY_POINT_GROUP = "silpose.commands"


def _print_version(value: bool) -> None:
    if value:
        print(f"silpose {silpose_version()}")
        raise typer.Exit(0)


def _root(
    version: bool = typer.Option(False, "--version", callback=_print_version, is_eager=True,
                                 help="Print the silpose version and exit."),
) -> None:
    """Infer 3D body structure from multi-view silhouettes: generate data in Blender, fit the shape+structure
    prior (mixture of PPCA), infer joints, evaluate."""


class SilposeGroup(typer.core.TyperGroup):
    """The root command: every error ends the run with one line, ``silpose CMD: error: <what> (<flag>)``, and
    exit status 2 (usage and input errors) or 1 (failures while running); docs/conventions.md, "Errors".
    click would print the usage, a hint and a boxed ``Error:`` instead."""

    def main(self, args=None, prog_name=None, complete_var=None, standalone_mode=True, **extra):
        from typer._click.exceptions import ClickException, NoArgsIsHelpError, UsageError
        from typer.exceptions import Abort

        try:
            rv = super().main(args=args, prog_name=prog_name, complete_var=complete_var, standalone_mode=False,
                              **extra)
            code = rv if isinstance(rv, int) else 0
        except NoArgsIsHelpError as exc:  # ``silpose`` alone: the help, as click shows it
            exc.show()
            code = exc.exit_code
        except UsageError as exc:
            where = exc.ctx.command_path if exc.ctx is not None else "silpose"
            print(f"{where}: error: {usage_message(exc)}", file=sys.stderr)
            code = 2
        except ClickException as exc:
            print(f"silpose: error: {exc.format_message()}", file=sys.stderr)
            code = exc.exit_code
        except Abort:
            print("silpose: interrupted", file=sys.stderr)
            code = 130
        if standalone_mode:
            sys.exit(code)
        return code


def usage_message(exc) -> str:
    """A click usage error as ``<what> (<flag>)``: ``-1 is not in the range x>=0 (--seed)``."""
    from typer._click.exceptions import BadParameter, MissingParameter

    if isinstance(exc, BadParameter) and not isinstance(exc, MissingParameter) and exc.message:
        hint = exc.param_hint
        if hint is None and exc.param is not None:
            hint = exc.param.get_error_hint()
        if hint is not None:
            if not isinstance(hint, str):
                hint = " / ".join(hint)
            return f"{exc.message} ({hint.replace(chr(39), '')})"
    return " ".join(exc.format_message().split())


def build_app() -> typer.Typer:
    app = typer.Typer(
        name="silpose",
        cls=SilposeGroup,
        no_args_is_help=True,
        add_completion=False,
        pretty_exceptions_enable=False,
        # click's plain help: it rewraps paragraphs to the terminal and never cuts an option name or a default
        # (rich's option table squeezed them into "--structure-weig…" at 80 columns); docs/conventions.md
        rich_markup_mode=None,
    )
    app.callback()(_root)
    for ep in sorted(entry_points(group=ENTRY_POINT_GROUP), key=lambda e: e.name):
        try:
            func = ep.load()
        except Exception as exc:  # a broken plugin must not take the whole CLI down
            print(f"silpose: cannot load command {ep.name!r} from {ep.value}: {exc}", file=sys.stderr)
            continue
        if isinstance(func, typer.Typer):  # a group of subcommands (e.g. ``silpose rig import``)
            _whole_summaries(func)
            app.add_typer(func, name=ep.name, short_help=summary(func.info.help))
        else:
            app.command(name=ep.name, short_help=summary(func.__doc__))(func)
    return app


def _whole_summaries(group: typer.Typer) -> None:
    """Give every subcommand of ``group`` (recursively) its whole first paragraph as the command list's line."""
    for info in group.registered_commands:
        if info.short_help is None:
            info.short_help = summary(info.help or getattr(info.callback, "__doc__", None))
    for sub in group.registered_groups:
        _whole_summaries(sub.typer_instance)


def summary(doc: object) -> str | None:
    """A command's first paragraph on one line: the command list shows it whole, wrapped to the terminal
    (click would cut it at about 45 characters with "...")."""
    if not isinstance(doc, str) or not doc.strip():
        return None
    import inspect

    return " ".join(inspect.cleandoc(doc).split("\n\n")[0].split())


def fail(command: str, message: str, code: int = 2) -> None:
    """End a subcommand with a one-line error on stderr (``silpose <command>: error: <message>``) and
    exit status ``code`` (2 = bad input, 130 = interrupted)."""
    print(f"silpose {command}: error: {message}", file=sys.stderr)
    raise typer.Exit(code)


@contextmanager
def lazy_progress(progress):
    """Yield a rich ``Progress`` that is not started yet; the caller starts it with :func:`show_progress` at its
    first step, and it is stopped at the end only if it was started. An input error found before the first step
    is then the only line on the terminal (a started display leaves a blank line behind)."""
    try:
        yield progress
    finally:
        if progress.live.is_started:
            progress.stop()


def show_progress(progress) -> None:
    """Start ``progress`` (from :func:`lazy_progress`) unless it runs already."""
    if not progress.live.is_started:
        progress.start()


def repair_wheel_tags() -> None:
    """Correct installed ``WHEEL`` tags that make ``uv run`` reinstall a package (bpy 5.0.1) on every
    call (see ``silpose.shared.wheel_tags``); reads ~100 small files, writes only when one is wrong."""
    from .wheel_tags import repair

    try:
        for r in repair():
            print(f"silpose: repaired the installed metadata of {r.describe()} (uv reinstalled it on every run)",
                  file=sys.stderr)
    except OSError as exc:  # a read-only environment: uv's churn stays, silpose still runs
        print(f"silpose: cannot repair installed wheel tags ({exc})", file=sys.stderr)


def main() -> None:
    repair_wheel_tags()
    build_app()()


if __name__ == "__main__":
    main()
