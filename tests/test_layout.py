"""The package's layout: no import circles, layers imported one way, modules of one job.

The imports are read with `ast` from the sources (every ``import``, at module level or
inside a function), so a circle hidden in a function-level import counts too.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import sparsekin

PACKAGE = Path(sparsekin.__file__).resolve().parent
#: The layers, lowest first: a module may import from its own layer and the ones below.
#: ``errors`` and ``_jit`` are below all; the package's ``__init__``, ``__main__`` and
#: ``testset`` are above all (they gather the public API and build models).
LAYERS = ("model", "engine", "analysis", "results", "solve", "studies", "plots", "cli")
FOUNDATION = {"errors", "_jit"}
TOP = {"", "__main__", "testset"}
#: Longest module, in lines.
MAX_LINES = 800


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _modules() -> dict[str, Path]:
    return {_module_name(path): path for path in sorted(PACKAGE.rglob("*.py"))}


def _imports(name: str, path: Path, modules: dict[str, Path]) -> set[str]:
    """The package's modules that module `name` imports (names below ``sparsekin``)."""
    is_package = path.name == "__init__.py"
    package = name.split(".") if is_package else name.split(".")[:-1]
    package = [part for part in package if part]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[: len(package) - (node.level - 1)] if node.level > 1 else list(package)
                target = ".".join([*base, *(node.module.split(".") if node.module else [])])
            elif node.module and (node.module == "sparsekin" or node.module.startswith("sparsekin.")):
                target = node.module.removeprefix("sparsekin").lstrip(".")
            else:
                continue
            for alias in node.names:  # `from package import module` imports that module
                child = f"{target}.{alias.name}" if target else alias.name
                found.add(child if child in modules else target)
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("sparsekin."):
                    found.add(alias.name.removeprefix("sparsekin."))
    found.discard(name)
    return {module for module in found if module in modules}


def _graph() -> dict[str, set[str]]:
    modules = _modules()
    return {name: _imports(name, path, modules) for name, path in modules.items()}


def _circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan), each sorted."""
    index, low, on_stack, stack, components = {}, {}, set(), [], []
    counter = [0]

    def visit(node: str) -> None:
        index[node] = low[node] = counter[0]
        counter[0] += 1
        stack.append(node)
        on_stack.add(node)
        for target in graph[node]:
            if target not in index:
                visit(target)
                low[node] = min(low[node], low[target])
            elif target in on_stack:
                low[node] = min(low[node], index[target])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                on_stack.discard(member)
                component.append(member)
                if member == node:
                    break
            if len(component) > 1:
                components.append(sorted(component))

    for node in graph:
        if node not in index:
            visit(node)
    return components


def _layer(module: str) -> int:
    head = module.split(".")[0]
    if module in FOUNDATION:
        return -1
    if module in TOP:
        return len(LAYERS)
    return LAYERS.index(head)


def test_no_import_circle():
    assert _circles(_graph()) == []


def test_the_circle_finder_finds_a_circle():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert _circles(graph) == [["a", "b", "c"]]


def test_layers_import_downwards_only():
    upward = [
        f"{module} imports {target}"
        for module, targets in _graph().items()
        for target in targets
        if _layer(target) > _layer(module)
    ]
    assert upward == []


def test_every_module_belongs_to_a_layer():
    for module in _modules():
        if module not in FOUNDATION | TOP:
            assert module.split(".")[0] in LAYERS, module


@pytest.mark.parametrize("module", sorted(_modules()))
def test_module_is_short(module):
    lines = len(_modules()[module].read_text().splitlines())
    assert lines <= MAX_LINES, f"sparsekin/{module}: {lines} lines"


#: The public API before the layout change (issue 17): ``sparsekin.__all__`` is unchanged.
PUBLIC_API = (
    "GROUND AbsoluteDriver AnalysisInterrupted Analysis Body ConvergenceError CoordinateMotion Cycle "
    "DistanceDriver DriverForce Force Gear Harmonic JacobianAnalysis KinematicStepper KinematicsResult Law "
    "LimitWarning Linear Mechanism ModelError ModelReport PathDriver PinInSlot PointMotion Polynomial "
    "RackPinion Reaction RedundantConstraintWarning Repeat Revolute Rigid RotationalDriver "
    "SingularConfigurationError SingularJacobianError SparsekinError Spline Spring Step Torque Translational "
    "TranslationalDriver Unit analyse_jacobian check_model load_model save_model solve_kinematics SweepResult "
    "VariantSet Workspace sweep workspace"
).split()


def test_public_api_is_kept():
    assert set(PUBLIC_API) <= set(sparsekin.__all__)
    for name in sparsekin.__all__:
        assert getattr(sparsekin, name) is not None, name


#: Functions of the kernel modules that run in Python on purpose (set-up around the kernels).
PYTHON_HELPERS = {
    "sparsekin.solve._error_control_kernels": {"control_rules", "control_state", "restore_controller"},
}


@pytest.mark.parametrize("module", [f"sparsekin.{name}" for name in _modules() if name.endswith("_kernels")])
def test_every_kernel_is_compiled(module):
    """A kernel module's functions are numba dispatchers (a lost ``@njit`` only shows as a
    slow run: a merge once dropped one), besides its declared Python helpers."""
    import importlib
    import inspect

    import numba

    if numba.config.DISABLE_JIT:
        pytest.skip("NUMBA_DISABLE_JIT=1: every kernel is plain Python")
    imported = importlib.import_module(module)
    plain = {name for name, value in vars(imported).items()
             if inspect.isfunction(value) and value.__module__ == module}  # fmt: skip
    assert plain == PYTHON_HELPERS.get(module, set())
