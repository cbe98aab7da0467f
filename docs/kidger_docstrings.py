"""A MyST parser for the docstrings, which are Markdown in the Kidger (mkdocstrings)
style: `!!! note "Title"` and `??? cite "References"` admonitions (their body
indented by four spaces) become MyST `{note}` / `{dropdown}` fences; the rest is
Markdown already."""

import re

from myst_parser.parsers.sphinx_ import MystParser


_ADMONITION = re.compile(r'^(?P<indent> *)(?P<mark>!!!|\?\?\?) +(?P<kind>\w+)'
                         r'(?: +"(?P<title>[^"]*)")? *$')
_KINDS = {"note": "note", "warning": "warning", "tip": "tip", "info": "note",
          "example": "note", "cite": "note", "danger": "danger"}


def convert(text: str) -> str:
    lines = text.splitlines()
    out = []
    i = 0
    while i < len(lines):
        match = _ADMONITION.match(lines[i])
        if not match:
            out.append(lines[i])
            i += 1
            continue
        indent = match["indent"]
        body = []
        i += 1
        while i < len(lines) and (not lines[i].strip()
                                  or lines[i].startswith(indent + "    ")):
            body.append(lines[i][len(indent) + 4:] if lines[i].strip() else "")
            i += 1
        while body and not body[-1]:
            body.pop()
        kind = _KINDS.get(match["kind"], "note")
        title = match["title"] or match["kind"].capitalize()
        if match["mark"] == "???":  # collapsed in mkdocs: a titled admonition here
            out += [f"{indent}:::{{admonition}} {title}", f"{indent}:class: {kind}"]
        elif match["title"]:
            out += [f"{indent}:::{{admonition}} {title}", f"{indent}:class: {kind}"]
        else:
            out.append(f"{indent}:::{{{kind}}}")
        out += [indent + line if line else "" for line in body]
        out += [f"{indent}:::", ""]
    return "\n".join(out)


class Parser(MystParser):
    """MyST, after turning mkdocs admonitions into MyST fences."""

    def parse(self, inputstring: str, document) -> None:
        super().parse(convert(inputstring), document)
