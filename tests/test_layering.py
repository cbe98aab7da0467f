"""The package's layering (docs/developers.md, "Layers"): every module of `jaxcontact/`,
parsed with `ast`, imports only modules at or below its own layer (at any level: a
function-level import counts the same), and no module imports another module's
private (underscore) names, by `from m import _x` or as `m._x`."""

import ast
from pathlib import Path

import pytest


PACKAGE = Path(__file__).resolve().parents[1] / "jaxcontact"

# Lowest first. A module may import a module of an earlier entry or of its own entry
# (an entry naming a package, `_solver`, covers its submodules). The package's
# `__init__` (`jaxcontact`, the public API) sits below the command line only.
LAYERS = [
    "_validate", "_results", "_version", "_cache", "_lee_radok",
    "_grid", "_influence", "_operator", "_ring_operator",
    "_material", "_material.base", "_material.checks", "_material.prony",
    "_material.elastic", "_material.maxwell", "_material.zener",
    "_indenter", "_probe", "_loading", "_history", "_analytic", "_scene",
    "_dataset", "_solution", "_solver", "_solve_normal", "_subsurface",
    "_solve_rings", "_solve", "_surface", "_sweep_dask", "_sweep",
    "fitting.options", "fitting.parametrisation", "fitting.result", "fitting.data",
    "fitting.model", "fitting.rings_model", "fitting.lbfgs", "fitting.lm",
    "fitting.certificate",
    "fitting.discretisation", "fitting.start", "fitting.fit", "fitting.batch",
    "fitting", "fitting.floor", "fitting.quality", "fitting.uncertainty",
    "fitting.afm",
    "_afm", "_force_map", "presets", "plot",
    "",  # jaxcontact/__init__.py
    "_cli_output", "_cli_fit", "_cli", "__main__",
]

# Entries that name a package whose submodules share its layer.
SUBPACKAGES = {"_solver"}

# (importing module, imported module, private name): why it is allowed.
ALLOWED_PRIVATE: dict[tuple[str, str, str], str] = {}


def _modules() -> dict[str, Path]:
    """`{dotted name below jaxcontact ("" for the package): path}`."""
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = list(path.relative_to(PACKAGE).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


MODULES = _modules()


def _layer(module: str) -> int:
    """Index of the entry of `LAYERS` that covers `module`."""
    for i, entry in enumerate(LAYERS):
        if module == entry or entry in SUBPACKAGES and module.startswith(entry + "."):
            return i
    raise AssertionError(f"{_dotted(module)} has no place in LAYERS "
                         "(tests/test_layering.py): add it")


def _imports(module: str, path: Path):
    """`(line, imported module, name or None, bound name)` for every import of a
    jaxcontact module in `path`, at any level; `name` is the name taken from the
    module by `from module import name` (None for a submodule or a plain import)."""
    is_package = path.name == "__init__.py"
    here = ["jaxcontact", *module.split(".")] if module else ["jaxcontact"]
    base = here if is_package else here[:-1]
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == "jaxcontact":
                    target = alias.name.removeprefix("jaxcontact").lstrip(".")
                    if alias.asname is None:  # binds the package itself
                        yield node.lineno, target, None, None
                        yield node.lineno, "", None, "jaxcontact"
                    else:
                        yield node.lineno, target, None, alias.asname
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                parts = base[: len(base) - node.level + 1]
                parts = [*parts, *(node.module.split(".") if node.module else [])]
            else:
                parts = node.module.split(".")
            if parts[0] != "jaxcontact":
                continue
            source = ".".join(parts[1:])
            for alias in node.names:
                sub = f"{source}.{alias.name}".lstrip(".")
                if sub in MODULES:  # a submodule: the module itself is imported
                    yield node.lineno, sub, None, alias.asname or alias.name
                else:
                    yield node.lineno, source, alias.name, alias.asname or alias.name


def _dotted(module: str) -> str:
    return f"jaxcontact.{module}" if module else "jaxcontact"


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__")
                                         and name.endswith("__"))


def upward_imports(module: str, path: Path) -> list[str]:
    """The imports in `path` (module `module`) of a module above its layer."""
    own = _layer(module)
    found = {(line, target) for line, target, _, _ in _imports(module, path)
             if _layer(target) > own}
    return [f"line {line}: {_dotted(target)} (above {_dotted(module)})"
            for line, target in sorted(found)]


def private_uses(module: str, path: Path) -> list[str]:
    """The private names of other modules that `path` (module `module`) imports
    (`from m import _x`) or reads from an imported module (`m._x`), less
    `ALLOWED_PRIVATE`."""
    found, aliases = [], {}
    for line, target, name, bound in _imports(module, path):
        if name is None:
            if bound is not None:
                aliases[bound] = target
        elif (_private(name) and target != module
              and (module, target, name) not in ALLOWED_PRIVATE):
            found.append(f"line {line}: from {_dotted(target)} import {name}")
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if not (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                and node.value.id in aliases and _private(node.attr)):
            continue
        target = aliases[node.value.id]
        if (f"{target}.{node.attr}".lstrip(".") not in MODULES and target != module
                and (module, target, node.attr) not in ALLOWED_PRIVATE):
            found.append(f"line {node.lineno}: {node.value.id}.{node.attr}")
    return found


def test_every_module_has_one_place_in_the_layers():
    for module in MODULES:
        _layer(module)
    assert len(LAYERS) == len(set(LAYERS))
    assert set(LAYERS) <= set(MODULES), set(LAYERS) - set(MODULES)


@pytest.mark.parametrize("module", sorted(MODULES))
def test_imports_only_at_or_below_its_layer(module):
    found = upward_imports(module, MODULES[module])
    assert not found, f"{_dotted(module)} imports upward: {found}"


@pytest.mark.parametrize("module", sorted(MODULES))
def test_no_private_name_of_another_module(module):
    found = private_uses(module, MODULES[module])
    assert not found, f"{_dotted(module)} uses private names: {found}"


def test_the_checks_find_an_upward_and_a_private_import(tmp_path):
    # A stand-in for jaxcontact/_grid.py (a package file: relative imports resolve
    # as there) with one violation of each kind at function level, one allowed
    # private module import and one public name.
    (tmp_path / "jaxcontact").mkdir()
    path = tmp_path / "jaxcontact" / "_grid.py"
    path.write_text(
        "from . import _validate\n"
        "def f():\n"
        "    from ._solve import solve\n"
        "    from ._scene import _check_program, Scene\n"
        "    return _validate.positive, _validate._hidden\n")
    assert upward_imports("_grid", path) == [
        "line 3: jaxcontact._solve (above jaxcontact._grid)",
        "line 4: jaxcontact._scene (above jaxcontact._grid)"]
    assert private_uses("_grid", path) == [
        "line 4: from jaxcontact._scene import _check_program",
        "line 5: _validate._hidden"]
