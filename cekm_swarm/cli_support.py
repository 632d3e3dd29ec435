"""What every ``cekm`` command shares: argument types that validate and name the option,
output directories that never mix two runs, and one error style with fixed exit codes.

Exit codes (``cekm_swarm.errors``): 0 done, 1 the run failed (``cekm: failed: ...``),
2 bad usage or input (``cekm: error: ...``), 130 interrupted (``cekm: interrupted``).
Every error is one line on stderr; a traceback means a bug.
"""

from __future__ import annotations

import math
import os
import re
import shutil
import sys
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any, TypeVar

import click

from .errors import EXIT_FAILED, EXIT_INTERRUPTED, EXIT_OK, EXIT_USAGE, CekmError, OutputDirError
from .protocol import KeySpaceError, validate_robot_id, validate_root, validate_run_id

# ---------------------------------------------------------------------------- types


class _Checked(click.ParamType[Any]):
    """A text option checked by ``check`` (a function raising CekmError or ValueError)."""

    def __init__(self, name: str, check: Callable[[str], Any]) -> None:
        self.name = name
        self._check = check

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        if not isinstance(value, str):
            return value
        try:
            return self._check(value)
        except (CekmError, ValueError) as exc:
            self.fail(str(exc), param, ctx)




def parse_size(text: str) -> int:
    """Bytes from ``500M``, ``2G``, ``64k``, ``1.5GB`` or ``1048576`` (k, M, G, T: powers of 1000;
    with ``i``, as in ``MiB``, of 1024); > 0."""
    m = re.fullmatch(r"\s*(\d+(?:\.\d+)?)\s*(?:([kKmMgGtT])(i?)[bB]?|[bB]?)\s*", text)
    if m is None:
        raise ValueError(f"{text!r} is not a size (e.g. 500M, 2G, 64k or 1048576 bytes)")
    unit = 1 if m[2] is None else (1024 if m[3] else 1000) ** ("kmgt".index(m[2].lower()) + 1)
    n = int(float(m[1]) * unit)
    if n <= 0:
        raise ValueError(f"{text!r}: a size must be more than 0 bytes")
    return n


class Finite(click.FloatRange):
    """A float option within an optional range that must be finite: ``nan`` and ``inf``
    (which ``float()`` and click's own ranges take) are refused naming the option."""

    name = "finite float"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        out = super().convert(value, param, ctx)
        if not math.isfinite(out):
            self.fail(f"{value!r} is not a finite number.", param, ctx)
        return out

    def _describe_range(self) -> str:
        """The bound shown in help; none for no bounds (click's own said ``x<=None``)."""
        return "" if self.min is None and self.max is None else super()._describe_range()


class RobotIds(click.ParamType[Any]):
    """Robot ids, comma-separated (``r1,r2``): at least one, each a valid robot id
    (:func:`cekm_swarm.protocol.keys.validate_robot_id`), none twice. ``none_word``: the
    word alone that means no robot (a tuple of none); ``count``: a plain number N means
    ``r1..rN`` (N >= 1)."""

    name = "robot ids"

    def __init__(self, none_word: str | None = None, count: bool = False) -> None:
        self._none = none_word
        self._count = count

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        if not isinstance(value, str):
            return value
        text = value.strip()
        if self._none is not None and text == self._none:
            return ()
        if self._count and text.isdigit():
            if int(text) < 1:
                self.fail(f"{value!r}: give at least one robot", param, ctx)
            return tuple(f"r{i + 1}" for i in range(int(text)))
        robots = tuple(r.strip() for r in text.split(","))
        if not text or any(not r for r in robots):
            self.fail(f"{value!r}: give robot ids separated by commas, e.g. r1,r2"
                      + (f" (or '{self._none}' for none)" if self._none else ""), param, ctx)
        twice = sorted({r for r in robots if robots.count(r) > 1})
        if twice:
            self.fail(f"{value!r}: {', '.join(twice)} given twice", param, ctx)
        for r in robots:
            try:
                validate_robot_id(r)
            except KeySpaceError as exc:
                self.fail(str(exc), param, ctx)
        return robots


SEED = click.IntRange(0, 2**32 - 1)
"""A seed: 0 .. 2^32 - 1 (what every random generator of the package accepts)."""
ROOT = _Checked("root", validate_root)
RUN_ID = _Checked("run id", validate_run_id)
SIZE = _Checked("size", parse_size)
"""A size in bytes, written 500M, 2G, 64k or 1048576 (:func:`parse_size`)."""


# ---------------------------------------------------------------------------- output directories


F = TypeVar("F", bound=Callable[..., Any])
"""A command function, as a click decorator takes and returns it."""


def out_dir_options(help_text: str) -> Callable[[F], F]:
    """``--out DIR`` (required) and ``--overwrite`` for a command that writes a directory."""

    def decorate(f: F) -> F:
        f = click.option("--overwrite", is_flag=True,
                         help="Clear a non-empty --out directory first (without it, one is refused).")(f)
        return click.option("--out", "out_dir", type=click.Path(file_okay=False, path_type=Path), required=True,
                            help=help_text)(f)

    return decorate


def out_file_option(help_text: str) -> Callable[[F], F]:
    """``--out FILE`` (required, as ``out_path``) for a command that writes one file (check it
    with :func:`prepare_out_file` or :func:`prepare_figure_file` before any work)."""
    return click.option("--out", "out_path", type=click.Path(dir_okay=False, path_type=Path), required=True,
                        help=help_text)


# ---------------------------------------------------------------------------- options every group shares

WORLD_SEED_HELP = "World seed (default: the scenario's)."


def seed_option(default: int | None = None, help_text: str = WORLD_SEED_HELP) -> Callable[[F], F]:
    """``--seed``: a :data:`SEED`; by default the world's (none given: the scenario's own)."""
    return click.option("--seed", type=SEED, default=default, show_default=default is not None, help=help_text)


def workers_option(help_text: str, default: int | None = None) -> Callable[[F], F]:
    """``--workers N``: how many processes a many-run command uses (N >= 1; none given, the
    command's ``default``, or its own rule when that is None)."""
    return click.option("--workers", type=click.IntRange(min=1), default=default, show_default=default is not None,
                        help=help_text)


quiet_option = click.option("--quiet", is_flag=True, help="No progress bar.")
"""``--quiet``: no progress bar."""


def prepare_out_dir(path: Path, overwrite: bool) -> Path:
    """Make ``path`` an empty directory for one run's files: a non-empty one is refused
    unless ``overwrite`` (then its contents are removed first), so a run never mixes its
    files with another's. Call it once the other arguments are checked, before writing."""
    if path.exists() and not path.is_dir():
        raise OutputDirError(f"--out {path}: exists and is not a directory")
    if path.is_dir():
        entries = sorted(p.name for p in path.iterdir())
        if entries:
            if not overwrite:
                shown = ", ".join(entries[:4]) + (", ..." if len(entries) > 4 else "")
                raise OutputDirError(f"--out {path}: not empty ({len(entries)} entries: {shown}); "
                                     f"give --overwrite to clear it first, or choose another directory")
            _refuse_to_clear(path)
            for p in path.iterdir():
                if p.is_dir() and not p.is_symlink():
                    shutil.rmtree(p)
                else:
                    p.unlink()
    missing = [p for p in path.absolute().parents if not p.exists()]
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:  # a parent that is a file, /proc, a read-only file system
        raise OutputDirError(f"--out {path}: cannot create the directory: {_os_reason(exc)}") from None
    if missing:  # fine, but said: a typo in a parent's name makes a new tree
        click.echo(f"note: --out {path}: created its missing parent {missing[-1]}", err=True)
    return path


def prepare_out_file(path: Path, option: str = "--out") -> Path:
    """Make sure the single file ``path`` can be written (its directory made, a new file
    creatable there), so an ``--out`` that cannot be written is one line naming it, before
    any work and not a traceback after it. An existing file is left as it is."""
    if path.is_dir():
        raise OutputDirError(f"{option} {path}: is a directory, not a file")
    blocked = next((p for p in path.parents if p.exists() or p.is_symlink()), None)
    if blocked is not None and not blocked.is_dir():
        raise OutputDirError(f"{option} {path}: cannot write the file: {blocked} is not a directory")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        if not path.exists():
            with open(path, "x"):
                pass
            path.unlink()
        elif not os.access(path, os.W_OK):
            raise PermissionError(13, "Permission denied")
    except OSError as exc:
        raise OutputDirError(f"{option} {path}: cannot write the file: {_os_reason(exc)}") from None
    return path


def prepare_figure_file(path: Path, option: str = "--out") -> Path:
    """:func:`prepare_out_file` for a figure matplotlib writes: its extension must name a
    format matplotlib can write (``.png``, ``.pdf``, ``.svg``, ...), checked before any work."""
    suffix = path.suffix[1:].lower()
    if suffix:
        from matplotlib.backend_bases import FigureCanvasBase

        formats = FigureCanvasBase.get_supported_filetypes()
        if suffix not in formats:
            raise OutputDirError(f"{option} {path}: cannot write a figure as .{suffix} "
                                 f"(formats: {', '.join(sorted(formats))})")
    return prepare_out_file(path, option)


def _os_reason(exc: OSError) -> str:
    return exc.strerror or str(exc)


def _refuse_to_clear(path: Path) -> None:
    here = Path.cwd().resolve()
    target = path.resolve()
    if target == Path(target.anchor) or target == Path.home().resolve() or here == target or target in here.parents:
        raise OutputDirError(f"--out {path}: refusing to clear {target} (the root, the home directory, "
                             f"or the working directory or one above it)")


# ---------------------------------------------------------------------------- errors


class RunFailed(click.ClickException):
    """A command's run failed (exit 1): the router unreachable, a process that did not come up."""

    exit_code = EXIT_FAILED


class FileRefused(click.ClickException):
    """An input file refused (a scenario, a graph; exit 2): its own line names the file,
    the field and the problem; no pointer to a command's --help, which does not describe
    the file format."""

    exit_code = EXIT_USAGE


class ScenarioFileError(FileRefused):
    """A scenario file refused (exit 2)."""


class Interrupted(click.ClickException):
    """The user stopped the command (Ctrl-C): exit 130, after what it could save was saved."""

    exit_code = EXIT_INTERRUPTED

    def __init__(self, message: str = "interrupted") -> None:
        super().__init__(message)


def say_error(kind: str, message: str) -> None:
    """One line on stderr: ``cekm: error: ...`` (usage) or ``cekm: failed: ...`` (a run)."""
    text = " ".join(str(message).split())  # one line, whatever the message held
    click.echo(f"cekm: {kind}: {text}" if kind else f"cekm: {text}", err=True)


def run_cli(group: click.Group, argv: list[str] | None = None) -> int:
    """Run the ``cekm`` group and map every outcome to one line and an exit code."""
    try:
        rv = group.main(args=argv, prog_name="cekm", standalone_mode=False)
    except click.exceptions.Exit as exc:
        return exc.exit_code
    except click.exceptions.Abort:
        say_error("", "interrupted")
        return EXIT_INTERRUPTED
    except KeyboardInterrupt:
        say_error("", "interrupted")
        return EXIT_INTERRUPTED
    except click.UsageError as exc:
        hint = f" (see '{exc.ctx.command_path} --help')" if exc.ctx is not None else ""
        say_error("error", exc.format_message() + hint)
        return EXIT_USAGE
    except Interrupted as exc:
        say_error("", exc.format_message())
        return EXIT_INTERRUPTED
    except click.ClickException as exc:
        say_error("failed" if exc.exit_code == EXIT_FAILED else "error", exc.format_message())
        return exc.exit_code
    except CekmError as exc:
        say_error("failed" if exc.exit_code == EXIT_FAILED else "error", str(exc))
        return exc.exit_code
    except BrokenPipeError:  # the reader of our output went away (``cekm topic echo | head``)
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())  # the interpreter's last flush goes nowhere
        os.close(devnull)
        return EXIT_OK
    return rv if isinstance(rv, int) else EXIT_OK


def check_seeds(seeds: Iterable[int]) -> None:
    """Every seed of ``--seeds`` fits the generators' 32-bit seeds, or a usage error naming the first that does not."""
    bad = [s for s in seeds if not 0 <= s < 2**32]
    if bad:
        raise click.UsageError(f"--seeds: every seed must be in 0..{2**32 - 1} (got {bad[0]})")
