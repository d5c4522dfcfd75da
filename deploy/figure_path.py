"""Where a figure goes (``--plot``, ``--png``): checked before any work, so a bad path is a
one-line mistake, not a traceback after the plan or report was computed."""

from __future__ import annotations

from pathlib import Path

from deploy.errors import UsageError

DEFAULT_SUFFIX = ".png"


def figure_path(text: str | Path, option: str) -> Path:
    """The file a figure will be written to: ``text``, with ``.png`` added when it has no
    suffix; UsageError if matplotlib is missing, cannot write that format, or the
    directory does not exist."""
    try:
        from matplotlib.backend_bases import FigureCanvasBase
    except ImportError:
        raise UsageError(f"{option} needs matplotlib: pip install 'mstc-swarm[plot]'") from None
    path = Path(text)
    if not path.suffix:
        path = path.with_name(path.name + DEFAULT_SUFFIX)
    formats = FigureCanvasBase.get_supported_filetypes()
    kind = path.suffix[1:].lower()
    if kind not in formats:
        raise UsageError(f"{option} {text}: cannot draw a .{kind} file; use one of "
                         f"{', '.join('.' + f for f in sorted(formats))}")
    parent = path.absolute().parent
    if not parent.is_dir():
        raise UsageError(f"{option} {text}: directory {parent} does not exist")
    return path


def save_figure(figure: object, path: Path, option: str, **options: object) -> None:
    """``figure.savefig(path)``; an unwritable file is a UsageError naming the option."""
    try:
        figure.savefig(path, **options)  # type: ignore[attr-defined]
    except OSError as error:
        raise UsageError(f"{option} {path}: cannot write: {error.strerror or error}") from None
