"""The public surface is the one documented in docs/ARCHITECTURE.md, and nothing more.

The table "Public surface" lists each sub-package's ``__all__`` exactly; these tests parse it
and compare. Every public name exists, is documented, is defined in the sub-package that
exports it (each object is exported once), and no module or private name leaks through
``__all__``. Pictures are drawn in ``shapetree.plotting`` only.
"""

from __future__ import annotations

import ast
import importlib
import inspect
import pkgutil
import re
import types
from pathlib import Path

import pytest

import shapetree

REPO = Path(__file__).resolve().parents[1]
DOC = REPO / "docs" / "ARCHITECTURE.md"
SRC = Path(shapetree.__file__).resolve().parent

#: Sub-packages whose owners have not yet applied the documented ``__all__`` (remove an
#: entry once its ``__all__`` matches: the strict xfail then fails as a reminder).
PENDING: dict[str, str] = {}


def _section(text: str, start: str, end: str) -> str:
    i = text.index(start)
    return text[i : text.index(end, i)]


def _table_rows(section: str) -> list[list[str]]:
    rows = []
    for line in section.splitlines():
        line = line.replace(r"\|", "\0")  # an escaped pipe inside a cell
        if not line.startswith("|") or set(line) <= set("|-: "):
            continue
        rows.append([c.strip().replace("\0", "|") for c in line.strip("|").split("|")])
    return rows[1:]  # drop the header


def _names(cell: str) -> list[str]:
    return re.findall(r"`([^`]+)`", cell)


def documented_surface() -> dict[str, list[str]]:
    text = DOC.read_text(encoding="utf-8")
    rows = _table_rows(_section(text, "## Public surface", "### Private modules"))
    out = {}
    for row in rows:
        (pkg,) = _names(row[0])
        module = "shapetree" if pkg == "shapetree" else f"shapetree.{pkg}"
        out[module] = _names(row[2])
    return out


def documented_private() -> dict[str, list[str]]:
    text = DOC.read_text(encoding="utf-8")
    rows = _table_rows(_section(text, "### Private modules shared", "## Key signatures"))
    return {" ".join(_names(row[0])): _names(row[2]) for row in rows}


SURFACE = documented_surface()


def _subpackages() -> list[str]:
    return sorted(
        f"shapetree.{m.name}"
        for m in pkgutil.iter_modules(shapetree.__path__)
        if m.ispkg and not m.name.startswith("_")
    )


def test_every_subpackage_is_documented():
    assert sorted(m for m in SURFACE if m != "shapetree") == _subpackages()
    assert "shapetree" in SURFACE
    for module, names in SURFACE.items():
        assert names, module
        assert len(names) == len(set(names)), f"{module}: a name is listed twice"


def _mark(module: str):
    if module in PENDING:
        return pytest.param(module, marks=pytest.mark.xfail(strict=True, reason=PENDING[module]))
    return module


@pytest.mark.parametrize("module", [_mark(m) for m in SURFACE])
def test_all_is_the_documented_list(module):
    mod = importlib.import_module(module)
    assert sorted(mod.__all__) == sorted(SURFACE[module])
    assert len(mod.__all__) == len(set(mod.__all__))


@pytest.mark.parametrize("module", list(SURFACE))
def test_public_names_exist_and_are_documented(module):
    mod = importlib.import_module(module)
    for name in mod.__all__:
        assert hasattr(mod, name), f"{module}.{name} is in __all__ but does not exist"
        obj = getattr(mod, name)
        if name == "__version__":
            continue
        if inspect.isclass(obj) or callable(obj):
            doc = obj.__doc__ or ""
            # a dataclass without a docstring gets its signature as __doc__
            assert doc.strip() and not doc.startswith(f"{obj.__name__}("), f"{module}.{name}"
        else:  # data: a ``#:`` comment right above its assignment (Sphinx autodoc style)
            assert _has_doc_comment(mod, name), f"{module}.{name}: no '#:' comment"


def _has_doc_comment(mod: types.ModuleType, name: str) -> bool:
    pattern = re.compile(rf"^#:.*\n(?:#:.*\n)*{re.escape(name)}\s*[:=]", re.M)
    folder = Path(mod.__file__).parent
    files = folder.glob("*.py") if mod.__file__.endswith("__init__.py") else [Path(mod.__file__)]
    return any(pattern.search(f.read_text(encoding="utf-8")) for f in files)


@pytest.mark.parametrize("module", list(SURFACE))
def test_no_private_name_or_module_leaks(module):
    mod = importlib.import_module(module)
    for name in mod.__all__:
        obj = getattr(mod, name)
        assert name == "__version__" or not name.startswith("_"), f"{module}.{name}"
        assert not isinstance(obj, types.ModuleType), f"{module}.{name} is a module"
    star: dict = {}
    exec(f"from {module} import *", star)  # noqa: S102 - what a user's star import gives
    star.pop("__builtins__")
    assert sorted(star) == sorted(mod.__all__)


def test_each_public_object_is_exported_once_by_its_own_subpackage():
    """One module per idea: a sub-package exports what it defines, and nothing twice."""
    seen: dict[int, str] = {}
    for module in SURFACE:
        mod = importlib.import_module(module)
        for name in mod.__all__:
            obj = getattr(mod, name)
            if not (inspect.isclass(obj) or inspect.isfunction(obj)):
                continue
            home = obj.__module__
            if module == "shapetree":
                assert home.startswith("shapetree."), f"{name}: from {home}"
            else:
                ok = home == module or home.startswith(module + ".")
                assert ok, f"{module}.{name} is defined in {home}"
            assert id(obj) not in seen, f"{module}.{name} also exported by {seen[id(obj)]}"
            seen[id(obj)] = f"{module}.{name}"


def test_documented_private_names_exist():
    for modules, names in documented_private().items():
        mods = [importlib.import_module(f"shapetree.{m}") for m in modules.split()]
        for name in names:
            assert any(hasattr(m, name) for m in mods), f"{modules}: {name}"


def _imports(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out.add(node.module)
    return out


#: Modules outside ``plotting`` allowed to import matplotlib, and what for.
MATPLOTLIB_ELSEWHERE = {
    "demo/_shapes.py": {"matplotlib.font_manager", "matplotlib.textpath"},  # glyph outlines
}


def test_pictures_are_drawn_in_plotting_only():
    for path in sorted(SRC.rglob("*.py")):
        rel = path.relative_to(SRC).as_posix()
        if rel.startswith("plotting/"):
            continue
        mpl = {m for m in _imports(path) if m.split(".")[0] == "matplotlib"}
        assert mpl <= MATPLOTLIB_ELSEWHERE.get(rel, set()), f"{rel} imports {sorted(mpl)}"
