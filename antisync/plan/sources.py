"""Where a config comes from: a YAML path, a mapping, a :class:`~antisync.plan.config.Config`
or a networkx graph object, with keyword overrides, as :func:`antisync.run` and the grid tools
take them, turned into one validated ``Config`` (:func:`resolve_config`).

Every value a caller hands in is checked here in one line naming the key (:func:`plain`:
plain YAML data only; :func:`file_path`: a path the system can store), before any file is
written.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Mapping
from dataclasses import fields, is_dataclass
from functools import cache
from pathlib import Path
from typing import Any, get_type_hints

import numpy as np

from antisync.errors import ConfigError
from antisync.physics.graphs import graph_spec
from antisync.plan.config import Config, apply_values, config_from_mapping, load_config

__all__ = [
    "file_path",
    "flag",
    "graph_object",
    "override_values",
    "plain",
    "resolve_config",
    "sections",
    "shown",
    "sweep_graphs",
]


@cache
def sections(*extra: type) -> frozenset[str]:
    """The config keys that are sections: a mapping of their own options, merged key by key.

    Read from the schema itself, so that a new section cannot be forgotten here: every field
    of :class:`~antisync.plan.config.Config` (and of ``extra``, e.g. the sweep's
    :class:`~antisync.sweeps.Sweep`) whose type is a dataclass, written as in a config file
    (``lambda_`` is ``lambda``). A field holding a whole config (a sweep's ``base``) is not a
    section. ``graph`` (a plain dict) is not a section: its ``kind`` decides its keys, so it is
    replaced whole.
    """
    classes = (Config, *extra)
    names = set()
    for cls in classes:
        hints = get_type_hints(cls)
        for f in fields(cls):
            kind = hints[f.name]
            if isinstance(kind, type) and is_dataclass(kind) and kind not in classes:
                names.add("lambda" if f.name == "lambda_" else f.name)
    return frozenset(names)


def flag(name: str, value) -> bool:
    """``value`` as a bool: True, False or a numpy bool; anything else is a :class:`ConfigError`."""

    if isinstance(value, bool | np.bool_):
        return bool(value)
    raise ConfigError(f"{name} must be True or False, got {shown(value)}")


def file_path(name: str, value, error: type[Exception]) -> Path:
    """``value`` (a str or an ``os.PathLike``) as a :class:`Path`, or ``error`` naming ``name``."""
    try:
        text = os.fspath(value) if isinstance(value, os.PathLike) else value
    except Exception:  # noqa: BLE001 -- a PathLike whose __fspath__ fails is no path
        text = None
    if not isinstance(text, str) or not text:
        raise error(f"{name} must be a file path (a non-empty str or pathlib.Path), got {shown(value)}")
    if "\0" in text:  # the operating system cannot name such a file: pathlib would raise ValueError
        raise error(f"{name} must be a file path, got {shown(text)}, which holds a NUL character")
    if any(ord(c) < 32 or ord(c) == 127 for c in text):
        # a line break or tab in a name is nearly always a line read without .strip(), and no
        # one-line message could show the name
        raise error(f"{name} {shown(text)} holds a control character (a line break, a tab); strip it")
    try:
        encoded = os.fsencode(text)
    except UnicodeEncodeError:  # a lone surrogate such as "\ud800": no file system can store it
        raise error(f"{name} {shown(text)} is not a file name this system can store") from None
    # checked here, before a folder on the way is made: the OS would refuse the name later
    longest = max((len(os.fsencode(part)) for part in Path(text).parts), default=0)
    if len(encoded) > _PATH_MAX or longest > _NAME_MAX:
        raise error(
            f"{name} {shown(text, 40)} is too long for a file path ({len(encoded)} bytes, a "
            f"name of {longest}; at most {_PATH_MAX} and {_NAME_MAX})"
        )
    return Path(text)


#: the longest file name and path (bytes) nearly every file system takes (Linux ext4, macOS APFS)
_NAME_MAX = 255
_PATH_MAX = 4095


def shown(value, limit: int = 80) -> str:
    """``value`` for a one-line message: its repr on one line, shortened, followed by its type
    unless it is None, a bool, an int, a float or a str (``array([1, 2]) (ndarray)``)."""
    try:
        text = repr(value)
    except Exception:  # noqa: BLE001 -- a huge int (Python refuses > 4300 digits) or a broken __repr__
        text = f"a {type(value).__name__} that cannot be printed"
        if isinstance(value, int):
            text = f"an integer of {value.bit_length()} bits"
        return text
    text = " ".join(text.split())
    if len(text) > limit:
        text = text[: limit - 3] + "..."
    if value is None or type(value) in (bool, int, float, str):
        return text
    return f"{text} ({type(value).__name__})"


def plain(value, key: str, _depth: int = 0):
    """``value`` as plain YAML data (None, bool, int, float, str, list, dict with str keys).

    numpy scalars become the Python numbers they hold (``np.int64(100)`` is ``100``), numpy
    arrays and tuples lists, paths (``os.PathLike``) strings. Anything else (bytes, sets,
    objects, cycles) is a :class:`ConfigError` naming ``key``: it could not be stored in the
    result file's YAML (yaml would raise a RepresenterError after the run had begun).
    """
    if _depth > 64:  # also ends a list that holds itself
        raise ConfigError(f"{key} is nested more than 64 levels deep (or holds itself); give plain YAML data")
    if value is None or type(value) in (bool, int, float):
        return value
    if isinstance(value, np.ndarray):
        value = value.tolist()
    elif isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, str):
        try:
            value.encode("utf-8")
        except UnicodeEncodeError:  # a lone surrogate: no YAML file or HDF5 attribute can hold it
            raise ConfigError(f"{key} must be text that UTF-8 can encode, got {shown(value)}") from None
    # subclasses (np.float64, an IntEnum, np.str_) as the plain type yaml.safe_dump knows
    for kind in (bool, int, float, str):
        if isinstance(value, kind):
            return kind(value)
    if isinstance(value, os.PathLike):
        return plain(os.fspath(value), key, _depth + 1)
    if isinstance(value, list | tuple):
        return [plain(v, f"{key}[{i}]", _depth + 1) for i, v in enumerate(value)]
    if isinstance(value, Mapping):
        out = {}
        for k, v in value.items():
            k = plain(k, key, _depth + 1) if isinstance(k, np.str_) else k
            if not isinstance(k, str):
                raise ConfigError(f"{key} must have string keys (names of config keys), got key {shown(k)}")
            out[k] = plain(v, f"{key}.{k}", _depth + 1)
        return out
    raise ConfigError(
        f"{key} must be plain YAML data (a number, string, true/false, None, list or mapping), "
        f"got {shown(value)}"
    )


def override_values(overrides: Mapping, output, sections: frozenset[str]) -> dict:
    """Keyword overrides -> dotted config keys: a mapping given to a section is merged into it
    key by key; any other value (``None`` too) replaces the key's value."""

    values: dict[str, Any] = {}
    for key, value in overrides.items():
        key = "lambda" if key == "lambda_" else key
        value = plain(value, key)
        if key in sections and isinstance(value, dict):
            for sub, v in value.items():
                values[f"{key}.{sub}"] = v
        else:
            values[key] = value
    if output is not None:
        values["output"] = str(file_path("output", output, ConfigError))
    return values


def resolve_config(config, overrides: Mapping, output) -> Config:
    """The validated :class:`Config` of :func:`run`'s ``config`` with ``overrides`` and
    ``output`` applied."""

    overrides = {k: graph_object(v) if k == "graph" else v for k, v in overrides.items()}
    values = override_values(overrides, output, sections())
    if isinstance(config, Config):
        raw = plain(config.to_dict(), "config")
    elif isinstance(config, Mapping):
        # a copy: the caller's mapping is left as it is
        raw = plain({k: graph_object(v) if k == "graph" else v for k, v in config.items()}, "config")
    else:
        return load_config(file_path("config", config, ConfigError), values=values)
    apply_values(raw, values)  # as load_config applies them to a file's mapping
    return config_from_mapping(raw)


def graph_object(value, where: str = "graph"):
    """A networkx graph object as its config graph spec (:func:`antisync.physics.graphs.graph_spec`,
    a one-line :class:`~antisync.physics.graphs.GraphError` naming ``where`` if it cannot be one);
    anything else as it is."""

    nx = sys.modules.get("networkx")  # a graph object exists only once networkx is imported
    if nx is None or not isinstance(value, nx.Graph):
        return value

    return graph_spec(value, where)


def sweep_graphs(section):
    """A sweep's ``sweep:`` section with the networkx graph objects of its ``graphs`` list as
    graph specs, named ``graph1``, ``graph2``, ... by their place in the list."""
    graphs = section.get("graphs") if isinstance(section, Mapping) else None
    if not isinstance(graphs, list | tuple):
        return section
    items = []
    for k, item in enumerate(graphs):
        spec = graph_object(item, f"sweep.graphs[{k}]")
        items.append({"name": f"graph{k + 1}", **spec} if spec is not item else item)
    return {**section, "graphs": items}
