"""The package's shape: no import circle among its modules, none over ~800 lines, the study tool
on the client's public names only."""

import ast
import re
from pathlib import Path

PKG = Path(__file__).resolve().parents[1] / "activefoam"
GENERATED = PKG / "v1"


def _modules():
    out = {}
    for f in sorted(PKG.rglob("*.py")):
        parts = f.relative_to(PKG.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = f
    return out


def _imports(f, mods):
    """The package's modules a file imports (anywhere in it, a function's lazy imports too)."""
    deps = set()
    for node in ast.walk(ast.parse(f.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("activefoam"):
            for a in node.names:
                full = f"{node.module}.{a.name}"
                deps.add(full if full in mods else node.module)
        elif isinstance(node, ast.Import):
            deps |= {a.name for a in node.names if a.name.startswith("activefoam")}
    return deps & set(mods)


def test_no_import_circle():
    mods = _modules()
    # A package's __init__ imports its modules (to re-export them): a module importing its
    # package is a circle too.
    graph = {m: _imports(f, mods) - {m} for m, f in mods.items()}
    state = {}

    def visit(m, path):
        state[m] = "open"
        for d in sorted(graph[m]):
            if state.get(d) == "open":
                raise AssertionError("import circle: " + " -> ".join(path[path.index(d):] + [d]))
            if d not in state:
                visit(d, path + [d])
        state[m] = "done"

    for m in mods:
        if m not in state:
            visit(m, [m])


def test_no_module_over_800_lines():
    long = {str(f.relative_to(PKG.parent)): n for f in PKG.rglob("*.py")
            if GENERATED not in f.parents and (n := len(f.read_text().splitlines())) > 800}
    assert not long, long


def test_the_study_tool_uses_the_clients_public_names_only():
    private = re.compile(r"from activefoam\.client import [^\n]*\b_\w+|\bclient\._\w+|\.job\(\S*\)\._")
    found = [f"{f.name}:{n}: {line.strip()}" for f in (PKG / "study").glob("*.py")
             for n, line in enumerate(f.read_text().splitlines(), 1) if private.search(line)]
    assert not found, found


def test_typed_and_versioned():
    assert (PKG / "py.typed").is_file()
    pyproject = (PKG.parent / "pyproject.toml").read_text()
    assert 'version = { attr = "activefoam.__version__" }' in pyproject
    assert re.search(r'^__version__ = "\d+\.\d+\.\d+"$', (PKG / "__init__.py").read_text(), re.M)
