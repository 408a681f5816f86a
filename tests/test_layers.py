"""Layering of the silpose sources, read from the AST alone (no module is imported).

Rules (docs/conventions.md, "Layers"): no import cycles between silpose modules; no upward
imports (shared -> {datagen, model, segment} -> app -> eval); no ``bench*.py`` module inside an
installed package (docs/conventions.md, "Benchmarks"); no citation of the design handout in any
``.py`` file of the repository (code cites docs/conventions.md); every silpose package that a
workspace member imports is declared in that member's ``pyproject.toml`` dependencies.

Every import counts: module level and inside functions, ``import a.b`` and ``from a import b``,
relative imports resolved against the importing module's package. The checker's own logic is
tested on a tiny planted tree (:func:`test_checker_finds_every_planted_problem`).
"""

from __future__ import annotations

import ast
import re
import tomllib
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

#: package -> silpose packages it must never import (shared is the bottom layer, eval the top).
FORBIDDEN: dict[str, frozenset[str]] = {
    "shared": frozenset({"datagen", "model", "segment", "app", "eval"}),
    "datagen": frozenset({"model", "segment", "app", "eval"}),
    "model": frozenset({"datagen", "segment", "app", "eval"}),
    "segment": frozenset({"datagen", "model", "app", "eval"}),
    "app": frozenset({"eval"}),
    "eval": frozenset(),
}
#: the handout citation, assembled so that this file does not contain it.
HANDOUT_CITATION = "DESIGN" + " §"


# ---------------------------------------------------------------------------------------- checker


def find_modules(repo: Path) -> dict[str, Path]:
    """Dotted name -> file of every module under ``<member>/src/silpose/**`` (packages by ``__init__``)."""
    found = {}
    for path in sorted(repo.glob("*/src/silpose/**/*.py")):
        src = path.parents[len(path.relative_to(repo).parts) - 3]  # <repo>/<member>/src
        parts = path.relative_to(src).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        found[".".join(parts)] = path
    return found


def _absolute(module: str, path: Path, node: ast.ImportFrom) -> str:
    """The absolute dotted name ``from ... import`` refers to (relative levels resolved)."""
    if node.level == 0:
        return node.module or ""
    package = module.split(".") if path.name == "__init__.py" else module.split(".")[:-1]
    if node.level - 1 > len(package) - 1:
        raise ValueError(f"{path}:{node.lineno}: relative import beyond the top-level package")
    base = package[: len(package) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def _owner(name: str, known: set[str]) -> str | None:
    """The longest known module that ``name`` is or lies in (None for other libraries)."""
    while name:
        if name in known:
            return name
        name = name.rpartition(".")[0]
    return None


def module_imports(module: str, path: Path, known: set[str]) -> set[str]:
    """Known silpose modules that ``module`` imports anywhere in its file (itself excluded).

    ``from P import x`` targets the module ``P.x`` when that is a module, else ``P``.
    """
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    targets: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = _absolute(module, path, node)
            names = [f"{base}.{a.name}" if f"{base}.{a.name}" in known else base for a in node.names]
        else:
            continue
        for name in names:
            owner = _owner(name, known)
            if owner is not None and owner != module:
                targets.add(owner)
    return targets


def import_graph(repo: Path) -> dict[str, set[str]]:
    """Module -> the silpose modules it imports."""
    mods = find_modules(repo)
    known = set(mods)
    return {m: module_imports(m, p, known) for m, p in mods.items()}


def find_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan, iterative), sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    components: list[list[str]] = []
    counter = 0
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            v, children = work[-1]
            w = next(children, None)
            if w is not None:
                if w not in graph:
                    continue
                if w not in index:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(sorted(graph[w]))))
                elif w in on_stack:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = []
                while True:
                    w = stack.pop()
                    on_stack.discard(w)
                    comp.append(w)
                    if w == v:
                        break
                if len(comp) > 1:
                    components.append(sorted(comp))
    return sorted(components)


def package_of(module: str) -> str:
    """``silpose.eval.run`` -> ``eval``."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else ""


def upward_imports(graph: dict[str, set[str]]) -> list[str]:
    """``"a -> b"`` for every import of a forbidden (higher or sibling) package."""
    return sorted(f"{m} -> {t}" for m, ts in graph.items() for t in ts
                  if package_of(t) in FORBIDDEN.get(package_of(m), frozenset()))


def benchmark_modules(repo: Path) -> list[str]:
    """Files named ``bench*.py`` inside installed packages, relative to ``repo``."""
    return sorted(str(p.relative_to(repo)) for p in find_modules(repo).values() if p.name.startswith("bench"))


def handout_citations(repo: Path) -> list[str]:
    """``file:line`` of every handout citation in the repository's ``.py`` files (hidden folders skipped)."""
    hits = []
    for path in sorted(repo.rglob("*.py")):
        rel = path.relative_to(repo)
        if any(part.startswith(".") or part == "__pycache__" for part in rel.parts[:-1]):
            continue
        for i, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            if HANDOUT_CITATION in line:
                hits.append(f"{rel}:{i}")
    return hits


def _requirement_name(req: str) -> str:
    return re.split(r"[\s<>=!~;\[(@]", req.strip(), maxsplit=1)[0].lower().replace("_", "-")


def undeclared_imports(repo: Path, graph: dict[str, set[str]]) -> list[str]:
    """``"member: silpose-x (imported by module)"`` for silpose packages a member imports without
    listing them in ``[project] dependencies`` of its ``pyproject.toml``."""
    members = tomllib.loads((repo / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["uv"]["workspace"]["members"]
    modules = find_modules(repo)
    problems: set[str] = set()
    for member in members:
        project = tomllib.loads((repo / member / "pyproject.toml").read_text(encoding="utf-8"))["project"]
        declared = {_requirement_name(r) for r in project.get("dependencies", [])}
        own = {package_of(m) for m, p in modules.items() if p.is_relative_to(repo / member)}
        for m in sorted(m for m, p in modules.items() if p.is_relative_to(repo / member)):
            for t in sorted(graph[m]):
                dist = f"silpose-{package_of(t)}"
                if package_of(t) not in own and dist not in declared:
                    problems.add(f"{member}: {dist} (imported by {m})")
    return sorted(problems)


# ---------------------------------------------------------------------------------------- the repository


@pytest.fixture(scope="module")
def graph():
    g = import_graph(REPO)
    # The walker really sees the code: a known edge at module level, one inside a function (cli
    # modules import their work lazily) and one through a relative import.
    assert len(g) > 50, sorted(g)
    assert "silpose.shared.dataset" in g["silpose.eval.run"]
    assert "silpose.eval.run" in g["silpose.eval.cli"]
    assert "silpose.shared.rig_frame" in g["silpose.shared.camera"]
    return g


def test_no_import_cycles(graph):
    cycles = find_cycles(graph)
    assert not cycles, "import cycles:\n" + "\n".join(" <-> ".join(c) for c in cycles)


def test_no_upward_imports(graph):
    bad = upward_imports(graph)
    assert not bad, "imports of a higher or sibling layer:\n" + "\n".join(bad)


def test_no_benchmark_modules_in_installed_packages():
    found = benchmark_modules(REPO)
    assert not found, "benchmarks belong in benchmarks/, not in installed packages:\n" + "\n".join(found)


def test_no_design_handout_citations():
    hits = handout_citations(REPO)
    assert not hits, "cite docs/conventions.md instead of the design handout:\n" + "\n".join(hits)


def test_every_imported_silpose_package_is_declared(graph):
    bad = undeclared_imports(REPO, graph)
    assert not bad, "undeclared workspace dependencies:\n" + "\n".join(bad)


# ---------------------------------------------------------------------------------------- the checker itself


def _write(root: Path, rel: str, text: str) -> None:
    path = root / rel
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8")


def _plant(root: Path, problems: bool) -> None:
    """A two-member workspace; with ``problems`` it holds one of each finding."""
    _write(root, "pyproject.toml", '[tool.uv.workspace]\nmembers = ["shared", "model"]\n')
    _write(root, "shared/pyproject.toml", '[project]\nname = "silpose-shared"\ndependencies = ["numpy>=1.26,<2"]\n')
    deps = '["numpy"]' if problems else '["silpose-shared", "numpy"]'
    _write(root, "model/pyproject.toml", f'[project]\nname = "silpose-model"\ndependencies = {deps}\n')
    _write(root, "shared/src/silpose/shared/__init__.py", "")
    _write(root, "shared/src/silpose/shared/a.py", "from .b import helper\n")
    # b -> a only inside a function: still a cycle
    _write(root, "shared/src/silpose/shared/b.py",
           "def helper():\n    from silpose.shared import a\n    return a\n" if problems else "def helper():\n    return 1\n")
    # an upward import hidden in a function, written as a plain ``import``
    _write(root, "shared/src/silpose/shared/c.py",
           "def late():\n    import silpose.model.m as m\n    return m\n" if problems else "X = 1\n")
    _write(root, "model/src/silpose/model/__init__.py", "")
    # a two-level relative import out of silpose.model into silpose.shared
    _write(root, "model/src/silpose/model/m.py", "from ..shared.a import helper\n")
    if problems:
        _write(root, "model/src/silpose/model/bench_fit.py", "print(1)\n")
        _write(root, "tools/notes.py", f"# see {HANDOUT_CITATION}4\n")
        _write(root, ".venv/lib/ignored.py", f"# {HANDOUT_CITATION}2 in a hidden folder does not count\n")


def test_checker_finds_every_planted_problem(tmp_path):
    _plant(tmp_path, problems=True)
    g = import_graph(tmp_path)
    assert g["silpose.model.m"] == {"silpose.shared.a"}  # relative import resolved two levels up
    assert g["silpose.shared.b"] == {"silpose.shared.a"}  # "from package import module" targets the module
    assert find_cycles(g) == [["silpose.shared.a", "silpose.shared.b"]]
    assert upward_imports(g) == ["silpose.shared.c -> silpose.model.m"]
    assert benchmark_modules(tmp_path) == ["model/src/silpose/model/bench_fit.py"]
    assert handout_citations(tmp_path) == ["tools/notes.py:1"]
    assert undeclared_imports(tmp_path, g) == ["model: silpose-shared (imported by silpose.model.m)",
                                               "shared: silpose-model (imported by silpose.shared.c)"]


def test_checker_passes_the_clean_tree(tmp_path):
    _plant(tmp_path, problems=False)
    g = import_graph(tmp_path)
    assert g["silpose.shared.a"] == {"silpose.shared.b"}
    assert find_cycles(g) == []
    assert upward_imports(g) == []
    assert benchmark_modules(tmp_path) == []
    assert handout_citations(tmp_path) == []
    assert undeclared_imports(tmp_path, g) == []


def test_cycle_finder_against_brute_force_reachability():
    """Tarjan's components equal the sets of mutually reachable nodes, on a random graph."""
    import random

    rnd = random.Random(0)
    nodes = [f"n{i}" for i in range(40)]
    g = {v: {w for w in nodes if w != v and rnd.random() < 0.04} for v in nodes}

    def reach(v):
        seen, todo = set(), [v]
        while todo:
            for w in g[todo.pop()]:
                if w not in seen:
                    seen.add(w)
                    todo.append(w)
        return seen

    r = {v: reach(v) for v in nodes}
    brute = {tuple(sorted({v} | {w for w in nodes if w in r[v] and v in r[w]})) for v in nodes}
    want = sorted(list(c) for c in brute if len(c) > 1)
    assert want, "the random graph should contain at least one cycle"
    assert find_cycles(g) == want
