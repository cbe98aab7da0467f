"""Sphinx configuration: MyST Markdown pages, the API reference by sphinx-autodoc2
from the docstrings (Markdown, Kidger style) without importing jaxcontact, the furo
theme. Build: `sphinx-build -W docs docs/_build/html` (tests/test_docs.py does it)."""

import sys
from pathlib import Path


HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))  # kidger_docstrings (the docstring parser)

project = "jaxcontact"
author = "the jaxcontact developers"
copyright = "2026, the jaxcontact developers"
release = version = "0.1.0"

extensions = ["myst_parser", "autodoc2", "sphinx.ext.mathjax"]
source_suffix = {".md": "markdown"}
exclude_patterns = ["_build"]
myst_enable_extensions = ["colon_fence", "dollarmath", "deflist"]
myst_heading_anchors = 3

# ---- API reference ------------------------------------------------------------------
autodoc2_packages = [
    {"path": "../jaxcontact", "module": "jaxcontact"},
]
autodoc2_render_plugin = "myst"
# The public API is what jaxcontact/__init__.py re-exports (its __all__).
autodoc2_module_all_regexes = [r"jaxcontact"]
autodoc2_hidden_objects = ["private", "dunder", "inherited"]
# The private modules are analysed (to resolve __all__) but get no pages of their own.
# The fitting package's public names are re-exported there too (jc.fit_afm_curve, ...).
autodoc2_skip_module_regexes = [r"jaxcontact\._.*", r"jaxcontact\.fitting.*"]
autodoc2_docstring_parser_regexes = [(r".*", "kidger_docstrings")]
autodoc2_class_docstring = "merge"
autodoc2_index_template = None



def _public_names():
    """`(private path, public path)` of every `from ._x import Y as Y` re-export, so
    that signatures and bases read `jaxcontact.Scene`, not `jaxcontact._scene.Scene`."""
    import ast

    tree = ast.parse((HERE.parent / "jaxcontact" / "__init__.py").read_text())
    pairs = []
    for node in tree.body:
        if isinstance(node, ast.ImportFrom) and node.level == 1 and node.module:
            for alias in node.names:
                if alias.asname == alias.name:
                    pairs.append((f"jaxcontact.{node.module}.{alias.name}",
                                  f"jaxcontact.{alias.name}"))
    return pairs


autodoc2_replace_annotations = _public_names()
autodoc2_replace_bases = _public_names()

html_theme = "furo"
html_title = "jaxcontact"
