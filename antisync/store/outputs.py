"""Where antisync may write an output file, and what an existing one must be to be replaced.

One policy for every file antisync writes beside its inputs (the removal table of ``antisync
grid --removal --out``, its ``--figure``), checked before any work and again when writing:

- the name ends in one of the writer's suffixes, its folder exists, and the path is not a
  folder, a device, a FIFO or a socket;
- a symbolic link is refused: the atomic rename that writes the file would replace the link,
  and the file behind it (a config, say) is never to be written through one;
- an input of the run (the config file and every file it reads: ``graph.path``,
  ``model.frequencies/inertia/damping.file``) is never an output, whatever the path's spelling
  (another folder, a link, a hard link: compared by ``os.path.samefile``);
- a path inside a ``*.partial`` folder is refused: antisync keeps an unfinished run's work
  there (a run's chunks, a removal's tasks), and a file written into it makes that run
  unresumable;
- an existing file is replaced only with ``--overwrite``, and only when it is a file of the
  kind the writer writes (``replaceable``: a removal table by its JSON ``format``, an image by
  its magic bytes): anything else is refused in one line and left as it is.

This module reads no HDF5 and imports nothing heavy; HDF5 result files have the same rules in
:mod:`antisync.store.lock` (``check_target``) and :mod:`antisync.store.result_store`.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Iterable
from pathlib import Path

from antisync.errors import StoreError

__all__ = [
    "JOURNAL_SUFFIX",
    "check_file_path",
    "check_output_path",
    "config_inputs",
    "image_problem",
    "journal_around",
    "json_format_problem",
]

#: Folders antisync keeps an unfinished run's work in: ``<output>.partial``.
JOURNAL_SUFFIX = ".partial"
#: The first bytes of each image kind a figure is written as.
_MAGIC = {".png": (b"\x89PNG\r\n\x1a\n", "a PNG image"), ".pdf": (b"%PDF", "a PDF document")}
#: How far into a file its image header is looked for (an SVG's ``<svg`` follows the XML
#: declaration and doctype; a PDF header may follow a few bytes of junk).
_HEAD_BYTES = 4096


def config_inputs(config, config_path: str | Path | None = None) -> list[tuple[Path, str]]:
    """The files a run of ``config`` reads, as ``(path, what)``: the config file itself
    (``config_path``), ``graph.path`` of a file graph and every ``model.*.file``.

    Parameters
    ----------
    config : Config or dict
        A validated :class:`~antisync.plan.config.Config` or its ``to_dict()`` (as stored in a
        removal table), with its paths resolved.
    config_path : path, optional
        The config file, when there is one.
    """
    d = config.to_dict() if hasattr(config, "to_dict") else dict(config or {})
    out = []
    if config_path is not None:
        out.append((Path(config_path), "the config file"))
    graph = d.get("graph")
    if isinstance(graph, dict) and isinstance(graph.get("path"), str):
        out.append((Path(graph["path"]), "the config's graph.path"))
    model = d.get("model")
    if isinstance(model, dict):
        for key in ("frequencies", "inertia", "damping"):
            spec = model.get(key)
            if isinstance(spec, dict) and isinstance(spec.get("file"), str):
                out.append((Path(spec["file"]), f"the config's model.{key}.file"))
    return out


def journal_around(path: str | Path) -> Path | None:
    """The ``*.partial`` folder that ``path`` lies in (as written, or once links are followed),
    or None."""
    path = Path(os.path.abspath(path))
    seen = [*path.parents]
    try:
        seen += [Path(os.path.realpath(path.parent)), *Path(os.path.realpath(path.parent)).parents]
    except OSError:  # a loop of links: the path is refused later as a folder that does not exist
        pass
    for folder in seen:
        if folder.name.endswith(JOURNAL_SUFFIX):
            return folder
    return None


def json_format_problem(path: str | Path, fmt: str) -> str | None:
    """What ``path`` is when it is not a JSON object whose ``format`` is ``fmt`` (None when it
    is one)."""
    try:
        with open(path, "rb") as fh:
            doc = json.loads(fh.read().decode("utf-8"))
    except (OSError, UnicodeDecodeError, ValueError):
        return "not a JSON file"
    if not isinstance(doc, dict) or doc.get("format") != fmt:
        return f"a JSON file without format {fmt!r}"
    return None


def image_problem(path: str | Path) -> str | None:
    """What ``path`` is when it is not an image of the kind its suffix names (``.png``,
    ``.pdf``, ``.svg``), by its first bytes; None when it is one."""
    path = Path(path)
    suffix = path.suffix.lower()
    try:
        with open(path, "rb") as fh:
            head = fh.read(_HEAD_BYTES)
    except OSError as exc:
        return f"a file that cannot be read ({exc.strerror or type(exc).__name__})"
    if suffix in _MAGIC:
        magic, what = _MAGIC[suffix]
        ok = head.startswith(magic) if suffix == ".png" else magic in head[:1024]
        return None if ok else f"not {what}"
    if suffix == ".svg":
        return None if b"<svg" in head else "not an SVG image"
    return f"not a {suffix or 'suffixed'} image antisync writes"


def check_file_path(path: Path, option: str, suffix: str, error: type[Exception] = StoreError) -> None:
    """The checks every output path of antisync passes (an HDF5 result file's too, see
    :meth:`antisync.store.lock.OutputLock.check_target`): not a symbolic link (the atomic rename
    would replace the link, not its target), not a folder, device, FIFO or socket, and not
    inside a ``*.partial`` journal folder (another run's unfinished work); one-line ``error``
    naming ``option`` otherwise."""
    if path.is_symlink():
        raise error(
            f"{option} {path} is a symbolic link (to {os.readlink(path)}); antisync replaces its output "
            "file and would replace the link, not its target: give the target's path or another file"
        )
    if path.is_dir():
        raise error(f"{option} {path} is a folder; give a file name ending in {suffix}")
    if path.exists() and not path.is_file():
        raise error(f"{option} {path} is not a regular file (a device, FIFO or socket); give another file")
    journal = journal_around(path)
    if journal is not None:
        raise error(
            f"{option} {path} lies inside {journal}, where antisync keeps an unfinished run's work; a "
            "file written there makes that run unresumable: give a path outside it"
        )


def check_output_path(
    path: str | Path,
    *,
    option: str,
    suffixes: tuple[str, ...],
    hint: str,
    overwrite: bool,
    replaceable: Callable[[Path], str | None],
    kind: str,
    protect: Iterable[tuple[Path, str]] = (),
    error: type[Exception] = StoreError,
) -> Path:
    """An output ``path`` checked before any work by the module's policy; one-line ``error``
    naming ``option`` otherwise.

    Parameters
    ----------
    path : path
        The output file.
    option : str
        The option that named it (``--out``, ``--figure``), for the messages.
    suffixes : tuple of str
        The valid suffixes (lower case, ``.json``); any other is refused with ``hint``.
    overwrite : bool
        Whether an existing file may be replaced (``--overwrite``, or a ``--resume`` that
        finishes it).
    replaceable : callable
        ``replaceable(path)``: None when the existing file is one this writer may replace,
        else what it is (``"not a JSON file"``).
    kind : str
        What ``replaceable`` accepts, for the message (``"an antisync removal table"``).
    protect : iterable of (path, what)
        Inputs of the run (:func:`config_inputs`): never an output.
    error : exception class
        Raised with the one-line message.

    Returns
    -------
    Path
        ``path``.
    """
    path = Path(path)
    if path.name in ("", ".", ".."):
        raise error(f"{option} {str(path)!r} names no file; give a file name ending in {suffixes[0]}")
    if path.suffix.lower() not in suffixes:
        raise error(f"{option} {path}: {hint}")
    check_file_path(path, option, suffixes[0], error)
    if not path.parent.is_dir():
        what = "is not a folder" if path.parent.exists() else "does not exist"
        raise error(f"{option} {path}: the folder {path.parent} {what}")
    if path.exists():
        for source, what in protect:
            try:
                same = os.path.samefile(path, source)
            except OSError:
                same = False
            if same:
                raise error(
                    f"{option} {path} is {what} ({source}), an input of this run: give another file "
                    "(it is left as it is)"
                )
    if path.exists():
        if not overwrite:
            raise error(f"{path} exists; pass --overwrite to replace it (it is left as it is)")
        problem = replaceable(path)
        if problem is not None:
            raise error(
                f"--overwrite replaces only {kind}, and {option} {path} is {problem}; it is left as it "
                "is: move it away or give another file"
            )
    return path
