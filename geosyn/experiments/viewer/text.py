"""Plain text inside the viewer's Markdown: names (a robot's file name, a run's name) are
shown as the characters they are, never read as Markdown or HTML."""

from __future__ import annotations

#: ASCII punctuation that CommonMark lets a backslash escape (every character that can
#: start or end a Markdown construct: links, emphasis, code, headings, tables, ...).
_MARKDOWN_PUNCTUATION = frozenset("\\`*_{}[]()#+-.!|~\"'$%,/:;=?@^")
#: Characters that start HTML or an entity: written as entities (shown as themselves).
_HTML = {"<": "&lt;", ">": "&gt;", "&": "&amp;"}


def markdown_text(text: str) -> str:
    """``text`` escaped for Markdown: it renders as exactly these characters.

    ``[x](javascript:alert(1))`` renders as that text, not as a link; ``<img ...>`` as
    text, not as an image; line breaks become spaces (a name is one line).

    Args:
        text: any string (a file name, a robot or run name).

    Returns:
        The escaped string, safe to put inside Markdown.
    """
    out = []
    for ch in " ".join(str(text).split()):
        if ch in _HTML:
            out.append(_HTML[ch])
        elif ch in _MARKDOWN_PUNCTUATION:
            out.append("\\" + ch)
        else:
            out.append(ch)
    return "".join(out)


__all__ = ["markdown_text"]
