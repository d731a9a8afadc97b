"""Imports run one way: the layer table in docs/design.md, no upward import, no cycle.

The imports are read from the source (``ast``), every ``import`` and ``from ... import`` in
a module, those inside functions and ``if TYPE_CHECKING:`` blocks included: a deferred import
is still a dependency, and a cycle through one is still a cycle.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "src" / "satsight"
DESIGN = ROOT / "docs" / "design.md"


def _layers() -> dict[str, int]:
    """{root name: layer rank} from the ```layers block of design.md (low to high)."""
    match = re.search(r"```layers\n(.*?)```", DESIGN.read_text(), flags=re.S)
    assert match, "docs/design.md has no ```layers block"
    ranks: dict[str, int] = {}
    for rank, line in enumerate(match.group(1).strip().splitlines()):
        for name in line.split():
            assert name not in ranks, f"{name} appears twice in the layer table"
            ranks[name] = rank
    return ranks


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in PACKAGE.rglob("*.py")}


def _imports(name: str, path: Path, modules: dict[str, Path]) -> set[str]:
    """The satsight modules that ``name`` imports (a package's ``__init__`` when a name
    is not a module of its own)."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                source = ".".join(base + ([node.module] if node.module else []))
            else:
                source = node.module or ""
            targets = [
                f"{source}.{alias.name}" if f"{source}.{alias.name}" in modules else source
                for alias in node.names
            ]
        else:
            continue
        for target in targets:
            while target and target not in modules:  # `import a.b.c` names a.b.c or above
                target = target.rpartition(".")[0]
            if target.startswith("satsight") and target != name:
                found.add(target)
    return found


def _graph() -> dict[str, set[str]]:
    modules = _modules()
    return {name: _imports(name, path, modules) for name, path in modules.items()}


def _root(module: str) -> str:
    """The layer-table name of a module: its subpackage or root module, or "satsight" for
    the package's own ``__init__`` (the facade)."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "satsight"


def test_every_package_and_root_module_has_a_layer():
    ranks = _layers()
    missing = sorted({_root(m) for m in _modules()} - set(ranks) - {"satsight"})
    assert not missing, f"add these to the ```layers block of docs/design.md: {missing}"
    stale = sorted(set(ranks) - {_root(m) for m in _modules()})
    assert not stale, f"the layer table names what does not exist: {stale}"


def test_no_module_imports_from_a_higher_layer():
    ranks = _layers()
    upward = [
        f"{a} -> {b}"
        for a, targets in sorted(_graph().items())
        if _root(a) != "satsight"  # the facade re-exports the interface
        for b in sorted(targets)
        if _root(b) == "satsight" or ranks[_root(b)] > ranks[_root(a)]
    ]
    assert not upward, "imports from a higher layer:\n" + "\n".join(upward)


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan's algorithm)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_no_import_cycles():
    cycles = _cycles(_graph())
    assert not cycles, "import cycles:\n" + "\n".join(" <-> ".join(c) for c in cycles)


@pytest.mark.parametrize(
    ("graph", "expected"),
    [
        ({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}, [["a", "b", "c"]]),
        ({"a": {"b"}, "b": set(), "c": {"b"}}, []),
        ({"a": {"b"}, "b": {"a"}, "c": {"d"}, "d": {"c"}}, [["a", "b"], ["c", "d"]]),
    ],
)
def test_cycle_finder_on_known_graphs(graph, expected):
    assert sorted(_cycles(graph)) == expected


def test_import_reader_sees_deferred_relative_and_dotted_imports(tmp_path, monkeypatch):
    package = tmp_path / "satsight"
    (package / "sub").mkdir(parents=True)
    (package / "__init__.py").write_text("")
    (package / "sub" / "__init__.py").write_text("")
    (package / "low.py").write_text("X = 1\n")
    (package / "sub" / "inner.py").write_text("Y = 2\n")
    (package / "sub" / "user.py").write_text(
        "def f():\n    from satsight.low import X\n    return X\n"
        "from . import inner\nimport satsight.sub.inner\nfrom ..low import X as Z\n"
    )
    monkeypatch.setattr(f"{__name__}.PACKAGE", package)
    modules = _modules()
    user = package / "sub" / "user.py"
    assert _imports("satsight.sub.user", user, modules) == {"satsight.low", "satsight.sub.inner"}
