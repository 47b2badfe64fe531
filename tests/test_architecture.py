"""The architecture holds: imports point one way down the layers, and no module or function
grows past the size a reader takes in at once (docs/architecture.md)."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "fatigue_pin"

# Each subpackage may import only from the subpackages before it in this list.
LAYERS = ("core", "robot", "fatigue", "muscles", "motors", "ocp", "drivers", "io", "verify", "sweep", "viz", "paper", "cli")
MAX_MODULE_LINES = 600
MAX_FUNCTION_LINES = 80
LONG_FUNCTION_NOTE = "Long because"  # a function over the limit says why in its docstring


def _modules() -> list[Path]:
    return sorted(p for p in PACKAGE.rglob("*.py") if "__pycache__" not in p.parts)


def _layer(module: str) -> str | None:
    """The subpackage of a dotted module name under fatigue_pin (None: the package itself)."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 and parts[0] == "fatigue_pin" and parts[1] in LAYERS else None


def _imports(path: Path) -> list[tuple[int, str]]:
    """Every fatigue_pin module imported anywhere in the file (module level or in a function)."""
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
            found += [(node.lineno, n) for n in names if n.startswith("fatigue_pin")]
        elif isinstance(node, ast.Import):
            found += [(node.lineno, a.name) for a in node.names if a.name.startswith("fatigue_pin")]
    return found


def test_every_module_is_in_a_layer():
    loose = [p.name for p in PACKAGE.glob("*.py") if p.name != "__init__.py"]
    assert loose == [], f"modules outside the subpackages: {loose}"
    folders = {p.name for p in PACKAGE.iterdir() if p.is_dir() and (p / "__init__.py").exists()}
    assert folders == set(LAYERS), folders ^ set(LAYERS)


def test_imports_point_down_the_layers():
    wrong = []
    for path in _modules():
        rel = path.relative_to(PACKAGE)
        if len(rel.parts) == 1:  # fatigue_pin/__init__.py: the public API gathers every layer
            continue
        own = LAYERS.index(rel.parts[0])
        for line, name in _imports(path):
            layer = _layer(name)
            if name in ("fatigue_pin", "fatigue_pin._pinocchio_casadi") or name.startswith("fatigue_pin._pinocchio_casadi"):
                continue  # the compiled extension sits beside the package, below every layer
            if layer is None:
                wrong.append(f"{rel}:{line} imports {name} (the top-level package; import from its module)")
            elif LAYERS.index(layer) > own:
                wrong.append(f"{rel}:{line} ({rel.parts[0]}) imports {name} ({layer}, a higher layer)")
    assert wrong == [], "\n".join(wrong)


def test_the_checker_sees_a_wrong_import(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text("def f():\n    from fatigue_pin.viz.plots import plot_run\n")
    assert [(2, "fatigue_pin.viz.plots"), (2, "fatigue_pin.viz.plots.plot_run")] == _imports(bad)
    assert _layer("fatigue_pin.viz.plots") == "viz" and LAYERS.index("viz") > LAYERS.index("robot")


def test_modules_and_functions_stay_small():
    long = []
    for path in _modules():
        text = path.read_text()
        rel = path.relative_to(PACKAGE)
        if len(text.splitlines()) > MAX_MODULE_LINES:
            long.append(f"{rel}: {len(text.splitlines())} lines (at most {MAX_MODULE_LINES})")
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = node.end_lineno - node.lineno + 1
                if n > MAX_FUNCTION_LINES and LONG_FUNCTION_NOTE not in (ast.get_docstring(node) or ""):
                    long.append(f"{rel}:{node.lineno} {node.name}: {n} lines (at most {MAX_FUNCTION_LINES}, "
                                f"or a docstring that says '{LONG_FUNCTION_NOTE} ...')")
    assert long == [], "\n".join(long)


def test_the_architecture_page_names_every_module():
    """docs/architecture.md's tree lists every module of every subpackage, under its subpackage."""
    text = (PACKAGE.parent / "docs" / "architecture.md").read_text()
    tree = text.split("```", 2)[1]
    blocks: dict[str, str] = {}
    current = None
    for line in tree.splitlines():
        head = line.replace("├──", "").replace("└──", "").strip().split("/")[0]
        if ("├──" in line or "└──" in line) and head in LAYERS:
            current = head
        if current is not None:
            blocks[current] = blocks.get(current, "") + line + "\n"
    missing = [f"{layer}/{p.name}" for layer in LAYERS for p in sorted((PACKAGE / layer).glob("*.py"))
               if p.name != "__init__.py" and p.name not in blocks.get(layer, "")]
    assert missing == [], f"modules missing from docs/architecture.md: {missing}"


def test_test_modules_have_unique_names():
    """pytest imports test files of folders without __init__.py by their basename: two of the
    same name stop the whole collection ("import file mismatch")."""
    names = [p.name for p in (Path(__file__).resolve().parent).rglob("test_*.py")]
    assert sorted({n for n in names if names.count(n) > 1}) == []
