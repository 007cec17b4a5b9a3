"""The package by layer (docs/architecture.md): every old name and path still imports, the layers
hold (import-linter), no module imports in a cycle, and the top level stays small."""

from __future__ import annotations

import ast
import importlib
import pkgutil
import subprocess
import sys
from pathlib import Path

import pytest

import upm
from upm import _moved

PACKAGE = Path(upm.__file__).parent

# `upm.__all__` before the layer packages: every name must still import from `upm`.
BEFORE = """PPOD_FIELDS PPOD_SEQUENCES BangBang BoardError ConvergenceError Disk DisplacementPlan DriveLimits
Equilibria FieldDesign FieldResult Harmonics InternalError MissingExtraError ParameterError PlanWarning
PlateMotion Point Polygon PredictivePlanner Pulse RadialField RankWarning ResonanceWarning RotationPlan
ShapeError SimResult SqueezeField StrokeError TwoHarmonic UpmError VisionError Waveform __version__
actuation asymptotic_field average_field build_info corner_centers design_field divergence_curl
drift_field feed_rate field_angle flow_error force_table grid_centers jet_field jet_plan jet_pulses mchip
mean_force orientation_equilibria plan_pulses plan_to_motion ring_centers rotation_curl rotation_field
rotation_order shapes simulate simulate_batch solve_displacements solve_rotations solve_rotations_batch
sustain_for_displacement sweep theorem1_force theory trim_rests""".split()


def test_every_name_of_before_still_imports() -> None:
    assert len(BEFORE) == 70
    missing = [n for n in BEFORE if not hasattr(upm, n)]
    assert not missing
    assert set(BEFORE) <= set(upm.__all__)


@pytest.mark.parametrize("old", sorted(_moved.MOVED))
def test_every_old_module_path_is_the_new_module(old: str) -> None:
    new = importlib.import_module(f"upm.{_moved.MOVED[old]}")
    assert importlib.import_module(f"upm.{old}") is new
    assert getattr(upm, old) is new
    assert sys.modules[f"upm.{old}"] is new
    assert new.__spec__ is not None and new.__spec__.name == new.__name__  # not the alias's spec


def test_from_old_path_import_name() -> None:
    from upm.drive import MAX_FREQUENCY, DriveLimits  # noqa: F401 - the import is the test
    from upm.plan import aligned_centers, aligned_centres
    from upm.sim import simulate

    assert simulate is upm.simulate and aligned_centres is aligned_centers


def _modules() -> list[str]:
    found = ["upm"]
    for info in pkgutil.walk_packages([str(PACKAGE)], "upm."):
        if not info.name.endswith("__main__"):
            found.append(info.name)
    return found


def test_every_module_imports() -> None:
    """Every module path under upm (the documented ones among them) imports."""
    failed = {}
    for name in _modules():
        try:
            importlib.import_module(name)
        except upm.MissingExtraError:
            continue
        except Exception as error:  # pragma: no cover - the message is the report
            failed[name] = repr(error)
    assert not failed


def _imports(path: Path, name: str) -> list[tuple[str, list[str]]]:
    """(module imported, names taken) of every relative or upm import in the file, anywhere."""
    is_package = path.name == "__init__.py"
    package = name if is_package else name.rsplit(".", 1)[0]
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target == "upm" or target.startswith("upm."):
                out.append((target, [a.name for a in node.names]))
        elif isinstance(node, ast.Import):
            out += [(a.name, []) for a in node.names if a.name.startswith("upm")]
    return out


def _sources() -> dict[str, Path]:
    found = {}
    for path in PACKAGE.rglob("*.py"):
        parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        found[".".join(parts)] = path
    return found


def test_the_root_gives_modules_only_the_extension() -> None:
    """import-linter reads `from .. import _core` (a compiled module it cannot see) as an import of
    the package root and the contract ignores those; so no module may take anything else from it."""
    taken = {}
    for name, path in _sources().items():
        if name == "upm":
            continue
        for target, names in _imports(path, name):
            if target == "upm" and set(names) - {"_core"}:
                taken[name] = names
    assert not taken


def test_no_module_imports_in_a_cycle() -> None:
    """Tarjan's components over every import (inside functions too), the root's `_core` aside."""
    sources = _sources()
    graph: dict[str, set[str]] = {}
    for name, path in sources.items():
        edges = set()
        for target, names in _imports(path, name):
            subs = [f"{target}.{n}" for n in names if f"{target}.{n}" in sources]
            edges |= set(subs) or ({target} if target in sources else set())
        graph[name] = edges - {"upm", name}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    cycles = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for v in graph:
        if v not in index:
            visit(v)
    assert not cycles


def test_the_layers_contract_holds() -> None:
    lint = Path(sys.executable).parent / "lint-imports"
    if not lint.exists():
        pytest.skip("import-linter is not installed (pip install 'upm[dev]')")
    out = subprocess.run([str(lint), "--no-cache"], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stdout[-3000:]


def test_the_top_level_is_the_face_and_ten_packages() -> None:
    packages = sorted(p.name for p in PACKAGE.iterdir() if (p / "__init__.py").exists())
    modules = sorted(p.stem for p in PACKAGE.glob("*.py") if not p.stem.startswith("_"))
    assert len(packages) <= 10, packages
    assert modules == ["cli"]


def test_no_source_file_over_600_lines() -> None:
    root = Path(__file__).resolve().parents[1]
    files = [*PACKAGE.rglob("*.py"), *(root / "crates").rglob("*.rs"), *(root / "tests").rglob("*.py")]
    long = {str(p): n for p in files if (n := len(p.read_text().splitlines())) > 600}
    assert not long


def test_the_tests_mirror_the_packages() -> None:
    # a folder of tests per package (tests of the whole face stay at the top)
    tests = Path(__file__).resolve().parent
    folders = {p.name for p in tests.iterdir() if p.is_dir() and any(p.glob("test_*.py"))}
    packages = {p.name for p in PACKAGE.iterdir() if (p / "__init__.py").exists()}
    assert folders and folders <= packages, folders - packages


def _rust_edges() -> dict[str, set[str]]:
    """Which crate-root modules of upm-core each crate-root module uses (`crate::x`, `super::x`
    from a file directly under `src/`), from the sources with comments and unit tests removed."""
    import re

    src = Path(__file__).resolve().parents[1] / "crates" / "upm-core" / "src"
    roots = {p.stem for p in src.glob("*.rs")} | {p.name for p in src.iterdir() if p.is_dir()}
    roots -= {"lib", "mod"}
    edges: dict[str, set[str]] = {r: set() for r in roots}
    for path in src.rglob("*.rs"):
        rel = path.relative_to(src).with_suffix("").parts
        if rel[0] not in roots:
            continue
        text = re.sub(r"#\[cfg\(test\)\]\s*mod tests\s*\{.*", "", path.read_text(), flags=re.S)
        text = re.sub(r"//[^\n]*", "", text)
        used = set(re.findall(r"\bcrate::(\w+)", text))
        if len(rel) == 1:  # a file under src/: its super is the crate
            used |= set(re.findall(r"\bsuper::(\w+)", text))
        edges[rel[0]] |= (used & roots) - {rel[0]}
    return edges


def test_no_cycle_among_the_cores_modules() -> None:
    """The crate-root modules of upm-core form no cycle (the vector build's choice lives in
    `simd`, below `sim`, `polygon`, `disk` and `stroke`, which all take it)."""
    edges = _rust_edges()
    assert "simd" in edges and "sim" not in edges["polygon"]
    seen: dict[str, int] = {}  # 1 on the path, 2 done

    def cycle_from(v: str, path: list[str]) -> list[str] | None:
        seen[v] = 1
        for w in sorted(edges[v]):
            if seen.get(w) == 1:
                return [*path[path.index(w) :], w] if w in path else [*path, w]
            if w not in seen and (found := cycle_from(w, [*path, w])):
                return found
        seen[v] = 2
        return None

    for v in sorted(edges):
        if v not in seen:
            assert cycle_from(v, [v]) is None
