"""The package's structure, read from its source: the layer order of docs/architecture.md, no
import circle, no function-local ``rcm_kin`` import in the library outside ``cli/`` and
``report/``, no cross-module ``_private`` import, size limits, and a model layer that names no
robot. The rules are parsed from the code (``ast``), not imported, so a violation fails here
whatever the code does at run time."""

from __future__ import annotations

import ast
import re
import tomllib
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src"
PACKAGE = SRC / "rcm_kin"

# lowest first: a module imports only from its own level or below (docs/architecture.md)
LAYERS = [
    ("errors", "atomic"),
    ("hardware", "thesis", "firmware_rules"),
    ("symbolic", "parallel", "apart", "progress"),
    ("csv_native", "csv_table"),
    ("model",),
    ("kinematics",),
    ("dynamics",),
    ("plotting", "figure_layout", "statics"),
    ("control",),
    ("codegen", "simulation", "identification", "export", "visualization"),
    ("robustness", "safety", "tuning", "ros2"),
    ("report",),
    ("cli",),
]
LEVEL = {name: level for level, names in enumerate(LAYERS) for name in names}
LOCAL_IMPORTS_ALLOWED = ("cli", "report")
MAX_MODULE_LINES = 400
MAX_FUNCTION_LINES = 80


def module_name(path: Path) -> str:
    parts = list(path.relative_to(SRC).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def top(module: str) -> str:
    """The first component below ``rcm_kin`` (``rcm_kin.model.robot`` -> ``model``)."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else ""


def resolve(node: ast.ImportFrom, module: str, is_package: bool) -> str:
    if node.level == 0:
        return node.module or ""
    base = module.split(".")[: (None if is_package else -1)]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def imports(module: str):
    """(imported module, imported name or None, line, inside a function, under TYPE_CHECKING) of
    every ``rcm_kin`` import of ``module``."""
    path = MODULES[module]
    tree = ast.parse(path.read_text())
    found = []

    def visit(node, in_function, type_checking):
        for child in ast.iter_child_nodes(node):
            func = in_function or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda))
            checking = type_checking or (isinstance(child, ast.If) and "TYPE_CHECKING" in ast.unparse(child.test))
            if isinstance(child, ast.ImportFrom):
                target = resolve(child, module, path.name == "__init__.py")
                if target == "rcm_kin" or target.startswith("rcm_kin."):
                    for alias in child.names:
                        full = f"{target}.{alias.name}"
                        if full in MODULES:
                            found.append((full, None, child.lineno, func, checking))
                        else:
                            found.append((target, alias.name, child.lineno, func, checking))
            elif isinstance(child, ast.Import):
                for alias in child.names:
                    if alias.name.startswith("rcm_kin"):
                        found.append((alias.name, None, child.lineno, func, checking))
            visit(child, func, checking)

    visit(tree, False, False)
    return found


LIBRARY = [m for m in MODULES if m != "rcm_kin"]


def test_every_package_has_a_layer():
    missing = sorted({top(m) for m in LIBRARY} - set(LEVEL))
    assert not missing, f"add {missing} to LAYERS (and docs/architecture.md)"


def public_home(name: str) -> str:
    """The subpackage a top-level public name (``from rcm_kin import simulate``) comes from, read
    from ``rcm_kin/__init__.py``'s ``_API`` table."""
    tree = ast.parse(MODULES["rcm_kin"].read_text())
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "_API" for t in node.targets):
            for key, value in zip(node.value.keys, node.value.values):
                if name in ast.literal_eval(value):
                    return f"rcm_kin.{ast.literal_eval(key)}"
    return f"rcm_kin.{name}" if f"rcm_kin.{name}" in MODULES else "rcm_kin"


@pytest.mark.parametrize("module", LIBRARY)
def test_imports_go_down_the_layers(module):
    here = LEVEL[top(module)]
    targets = [(public_home(name) if target == "rcm_kin" and name else target, line)
               for target, name, line, _, _ in imports(module)]
    upward = [f"line {line}: {target}" for target, line in targets
              if target != "rcm_kin" and LEVEL[top(target)] > here]
    assert not upward, f"{module} (level {here}) imports from a higher layer: {upward}"


def test_a_top_level_name_is_layered_by_its_home():
    assert public_home("simulate") == "rcm_kin.simulation" and public_home("RcmKinError") == "rcm_kin.errors"
    assert public_home("thesis") == "rcm_kin.thesis"


@pytest.mark.parametrize("module", [m for m in LIBRARY if top(m) not in LOCAL_IMPORTS_ALLOWED])
def test_no_function_local_rcm_kin_import(module):
    local = [f"line {line}: {target}" for target, _, line, in_function, _ in imports(module) if in_function]
    assert not local, f"{module} imports rcm_kin inside a function: {local}"


@pytest.mark.parametrize("module", LIBRARY)
def test_no_private_name_crosses_modules(module):
    private = [f"line {line}: {target}.{name}" for target, name, line, _, _ in imports(module)
               if name and name.startswith("_") and target != module]
    assert not private, f"{module} imports private names of other modules: {private}"


def test_no_import_circle():
    graph = {m: {t for t, _, _, in_function, checking in imports(m) if t in MODULES and t != m
                 and not in_function and not checking}
             for m in MODULES}
    # a package's __init__ is entered before its modules: importing rcm_kin.model.robot runs
    # rcm_kin.model first, so an __init__ importing its own modules is not a circle
    for m in graph:
        graph[m] = {t for t in graph[m] if not (MODULES[m].name == "__init__.py" and t.startswith(m + "."))}
    state, circles = {}, []

    def walk(node, stack):
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == 1:
                circles.append(stack[stack.index(nxt):] + [nxt])
            elif nxt not in state:
                walk(nxt, stack)
        stack.pop()
        state[node] = 2

    for m in sorted(graph):
        if m not in state:
            walk(m, [])
    assert not circles, "import circles: " + "; ".join(" -> ".join(c) for c in circles)


@pytest.mark.parametrize("module", LIBRARY)
def test_sizes(module):
    path = MODULES[module]
    text = path.read_text()
    lines = text.count("\n")
    assert lines <= MAX_MODULE_LINES, f"{module} has {lines} lines (at most {MAX_MODULE_LINES})"
    long = [f"{node.name} ({node.end_lineno - node.lineno + 1} lines)" for node in ast.walk(ast.parse(text))
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))
            and node.end_lineno - node.lineno + 1 > MAX_FUNCTION_LINES]
    assert not long, f"{module}: functions over {MAX_FUNCTION_LINES} lines: {long}"


@pytest.mark.parametrize("module", LIBRARY)
def test_no_assert_for_checks(module):
    """Checks raise errors: ``python -O`` removes asserts."""
    tree = ast.parse(MODULES[module].read_text())
    assert not [n.lineno for n in ast.walk(tree) if isinstance(n, ast.Assert)], f"{module} checks with assert"


@pytest.mark.parametrize("module", [m for m in LIBRARY if top(m) != "cli"])
def test_the_library_does_not_print(module):
    """The library warns through ``warnings`` and returns results; the CLI prints."""
    tree = ast.parse(MODULES[module].read_text())
    prints = [n.lineno for n in ast.walk(tree)
              if isinstance(n, ast.Call) and isinstance(n.func, ast.Name) and n.func.id == "print"]
    assert not prints, f"{module} prints (lines {prints})"


ROBOT_WORDS = re.compile(r"(?<![a-z])(psm|mtm|davinci|dvrk)(?![a-z])", re.I)


def strings_in_code(tree: ast.AST) -> list[str]:
    """Every string constant of ``tree`` but the docstrings (of the module, classes, functions)."""
    docstrings = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant):
                docstrings.add(id(first.value))
    return [node.value for node in ast.walk(tree) if isinstance(node, ast.Constant)
            and isinstance(node.value, str) and id(node) not in docstrings]


def test_the_robot_name_check_finds_robot_names():
    code = '"""A PSM docstring."""\nx = "load the PSM"\ny = f"{a} psm.toml"\nz = "mtm_arm"\n'
    assert [bool(ROBOT_WORDS.search(s)) for s in strings_in_code(ast.parse(code))] == [True, True, True]
    assert not ROBOT_WORDS.search("upsample and mtms_x")


@pytest.mark.parametrize("module", [m for m in MODULES if top(m) == "model"])
def test_the_model_layer_names_no_robot(module):
    """No robot name in the model layer's code (its strings, docstrings aside), and none of the
    bundled robots' joint names."""
    joint_names = set()
    for sidecar in (PACKAGE.parents[1] / "urdf").glob("*.toml"):
        joint_names |= set(tomllib.loads(sidecar.read_text()).get("actuated", []))
    named = [s for s in strings_in_code(ast.parse(MODULES[module].read_text()))
             if ROBOT_WORDS.search(s) or s in joint_names]
    assert not named, f"{module} names a robot or its joints: {named}"


@pytest.mark.parametrize("package", sorted({top(m) for m in LIBRARY if MODULES[m].name == "__init__.py"
                                            and m.count(".") == 1}))
def test_each_subpackage_lists_its_faces(package):
    import importlib

    mod = importlib.import_module(f"rcm_kin.{package}")
    if package in ("cli", "report"):
        return
    names = getattr(mod, "__all__", None)
    assert names, f"rcm_kin.{package} has no __all__"
    assert len(names) <= 12, f"rcm_kin.{package} lists {len(names)} names (at most a dozen)"
    for name in names:
        assert getattr(mod, name) is not None
    shadowed = sorted(set(names) & {p.stem for p in (PACKAGE / package).glob("*.py")})
    assert not shadowed, f"rcm_kin.{package} lists {shadowed}, which are also its modules' names"


def test_the_public_api_is_lazy_and_complete():
    import subprocess
    import sys

    import rcm_kin as rk

    for name in rk.__all__:
        assert getattr(rk, name).__doc__, f"rcm_kin.{name} has no docstring"
    out = subprocess.run([sys.executable, "-c", "import sys, rcm_kin; print(sorted(m for m in sys.modules "
                          "if m.startswith(('rcm_kin.', 'pinocchio', 'casadi', 'matplotlib', 'scipy'))))"],
                         capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]", f"import rcm_kin imported {out.strip()}"
