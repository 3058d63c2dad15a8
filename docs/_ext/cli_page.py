"""The command-line page as a user types it: plain defaults, addresses as literals.

sphinx-click writes a default as its Python ``repr`` (``'runs/train'``) and leaves an address
such as ``tcp://HOST:8786`` in running text, where docutils makes it a link. These handlers
rewrite the generated lines before they are parsed.
"""

from __future__ import annotations

import re
from typing import Any

_QUOTED_DEFAULT = re.compile(r"^(\s*:default: ``)'(.*)'(``)$")
_ADDRESS = re.compile(r"(?<![`\w])(tcp|tls|ws)://[\w.:<>-]+")


def plain_line(line: str) -> str:
    """One generated line with a string default unquoted and addresses as literals."""
    line = _QUOTED_DEFAULT.sub(r"\1\2\3", line)
    return _ADDRESS.sub(lambda match: f"``{match.group(0)}``", line)


def _rewrite(app: Any, ctx: Any, lines: list[str]) -> None:
    lines[:] = [plain_line(line) for line in lines]


def setup(app: Any) -> dict[str, Any]:
    """Connect the rewrite to sphinx-click's option, description and epilog events."""
    for event in ("options", "description", "epilog"):
        app.connect(f"sphinx-click-process-{event}", _rewrite)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
