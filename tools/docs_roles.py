"""A griffe extension for the API reference (``make docs``): Sphinx roles as code.

antisync's docstrings cite other objects the Sphinx way (``:func:`antisync.run```,
``:class:`~antisync.errors.ConfigError```), which numpy users' tools read; mkdocstrings shows
such a role as raw text. This extension rewrites each role to inline code of the name (the
last component for ``~`` names, as Sphinx shows them) when the docstrings are loaded.
"""

from __future__ import annotations

import re

import griffe

# :func:`name`, :class:`~a.b.C`, :py:meth:`x`, :data:`X` ... -> `name`, `C`, `x`, `X`
_ROLE = re.compile(r":(?:py:)?[a-z]+:`(~?)([^`<]+?)(?:\s*<([^`>]+)>)?`")


def _code(match: re.Match) -> str:
    tilde, text, target = match.groups()
    if target:  # :func:`shown text <target>`
        return f"`{text.strip()}`"
    return f"`{text.rsplit('.', 1)[-1] if tilde else text}`"


class SphinxRolesAsCode(griffe.Extension):
    """Rewrite Sphinx cross-reference roles in every docstring to inline code."""

    def on_instance(self, *, obj: griffe.Object, **kwargs) -> None:
        if obj.docstring is not None:
            obj.docstring.value = _ROLE.sub(_code, obj.docstring.value)
