"""A griffe extension for jaxbox's docstrings, used by the API reference (mkdocs.yml) and by the
documentation build's docstring check (``tools/docs_hooks.py``).

- **``#:`` comments.** jaxbox documents its constants the Sphinx way::

      #: Largest plausible RMSE [K] of a temperature output.
      MAX_RMSE = 5.0

  griffe reads only a string literal after the assignment; the ``#:`` lines directly above (or a
  trailing ``#: …`` on the same line) become the docstring of a constant that has none.
- **Shapes and units in brackets.** ``x0`` [S, n] [°C] reads in Markdown as a reference link
  ``[S, n][°C]``, which the site would report as a broken cross-reference. A ``[`` that follows
  ``]`` and blanks outside code spans is escaped, so both brackets show as written.
- **Sphinx roles** (``:func:`fit_model```, ``:class:`~jaxbox.data.Dataset```) read as code
  (``fit_model``, ``Dataset``) instead of showing the role's markup.
"""

from __future__ import annotations

import re

import griffe

_ROLE = re.compile(r":(?:py:)?(?:func|class|meth|data|mod|attr|obj|exc|const):`(~?)([^`]+)`")
_ADJACENT = re.compile(r"\](\s+)\[")
_CODE = re.compile(r"(``.*?``|`[^`]*`)", flags=re.S)


def comment_docstring(lines: list[str], lineno: int) -> str | None:
    """The ``#:`` comment of the assignment on line ``lineno`` (1-based) of ``lines``."""
    if lineno < 1 or lineno > len(lines):
        return None
    line = lines[lineno - 1]
    if "#:" in line:
        return line.split("#:", 1)[1].strip() or None
    found = []
    i = lineno - 2
    while i >= 0 and lines[i].lstrip().startswith("#:"):
        found.append(lines[i].lstrip()[2:].strip())
        i -= 1
    return "\n".join(reversed(found)) or None


def plain_roles(text: str) -> str:
    """Sphinx roles as code: ``:func:`fit``` → ```fit```, ``:class:`~a.b.C``` → ```C```."""

    def code(match: re.Match) -> str:
        target = match.group(2).strip()
        return f"`{target.rsplit('.', 1)[-1] if match.group(1) else target}`"

    return _ROLE.sub(code, text)


def escape_adjacent_brackets(text: str) -> str:
    """``] [`` outside code spans becomes ``] \\[``."""
    parts = _CODE.split(text)
    for i in range(0, len(parts), 2):  # the code spans are the odd parts
        parts[i] = _ADJACENT.sub(r"]\1\\[", parts[i])
    return "".join(parts)


class JaxboxDocstrings(griffe.Extension):
    """``#:`` comments as docstrings of constants; Sphinx roles as code; ``] [`` escaped."""

    def on_instance(self, *, node, obj, agent, **kwargs) -> None:
        if obj.is_attribute and obj.docstring is None and obj.lineno is not None:
            try:
                lines = list(obj.lines_collection[obj.filepath])
            except (KeyError, TypeError, AttributeError):
                lines = []
            text = comment_docstring(lines, obj.lineno)
            if text:
                obj.docstring = griffe.Docstring(text, lineno=obj.lineno, parent=obj)
        if obj.docstring is not None:
            obj.docstring.value = escape_adjacent_brackets(plain_roles(obj.docstring.value))
