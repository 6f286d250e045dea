"""The layers read top-down: the world (sim_backend/) and
host perception (perception/) import nothing from bridge/ (links, serial,
CLI), and the firmware (firmware_logic/) imports none of the host packages.
Every import statement counts, also one inside a function."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FORBIDDEN = {
    "sim_backend": {"bridge"},
    "perception": {"bridge"},
    "firmware_logic": {"bridge", "sim_backend", "perception"},
}


def imports(path: Path) -> list[tuple[int, str]]:
    out = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            out.append((node.lineno, node.module))
    return out


def offences(package: str, root: Path = ROOT) -> list[str]:
    bad = []
    for path in sorted((root / package).rglob("*.py")):
        for line, name in imports(path):
            if name.split(".")[0] in FORBIDDEN[package]:
                bad.append(f"{path.relative_to(root)}:{line}: imports {name}")
    return bad


@pytest.mark.parametrize("package", sorted(FORBIDDEN))
def test_a_lower_layer_imports_no_upper_one(package: str) -> None:
    assert not offences(package), "\n".join(offences(package))


def test_the_check_sees_an_import_inside_a_function(tmp_path: Path) -> None:
    probe = tmp_path / "sim_backend" / "probe.py"
    probe.parent.mkdir()
    probe.write_text("def f():\n    from bridge.links import codec\n    return codec\n")
    assert offences("sim_backend", root=tmp_path) == [
        "sim_backend/probe.py:2: imports bridge.links"]


def _module_graph(root: Path = ROOT) -> dict[str, set[str]]:
    """Each project module's module-level imports of other project modules."""
    files = {}
    for pkg in ("sim_backend", "bridge", "perception", "firmware_logic"):
        for p in (root / pkg).rglob("*.py"):
            parts = p.relative_to(root).with_suffix("").parts
            files[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = p
    graph: dict[str, set[str]] = {}
    for name, p in files.items():
        package = name if p.name == "__init__.py" else name.rpartition(".")[0]
        out = set()
        for node in ast.parse(p.read_text()).body:       # module level only
            if isinstance(node, ast.Import):
                out |= {a.name for a in node.names}
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    up = package.split(".")[: len(package.split(".")) - node.level + 1]
                    base = ".".join(up + ([node.module] if node.module else []))
                out.add(base)
                out |= {f"{base}.{a.name}" for a in node.names}
        graph[name] = {d for d in out if d in files and d != name and not name.startswith(d + ".")}
    return graph


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    seen: dict[str, int] = {}
    stack: list[str] = []
    found = []

    def visit(v: str) -> None:
        seen[v] = 1
        stack.append(v)
        for w in sorted(graph[v]):
            if seen.get(w) == 1:
                found.append(stack[stack.index(w):] + [w])
            elif w not in seen:
                visit(w)
        stack.pop()
        seen[v] = 2

    for v in sorted(graph):
        if v not in seen:
            visit(v)
    return found


def test_no_import_cycle_at_module_level() -> None:
    assert _cycles(_module_graph()) == []


def test_the_cycle_check_finds_a_cycle() -> None:
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == [["a", "b", "c", "a"]]


# -- docs/architecture.md's picture is the import graph ------------------------------

ARCHITECTURE = ROOT / "docs" / "architecture.md"
PACKAGES = ("bridge", "sim_backend", "perception", "firmware_logic")


def _block(info: str) -> list[str]:
    """The lines of the fenced block ```info in docs/architecture.md."""
    text = ARCHITECTURE.read_text(encoding="utf-8")
    start = text.index(f"```{info}\n") + len(f"```{info}\n")
    return [ln for ln in text[start:text.index("```", start)].splitlines() if ln.strip()]


def package_graph(root: Path = ROOT) -> dict[str, set[str]]:
    """Which package imports which (every import statement counts)."""
    graph: dict[str, set[str]] = {p: set() for p in PACKAGES}
    for package in PACKAGES:
        for path in (root / package).rglob("*.py"):
            for node in ast.walk(ast.parse(path.read_text(), str(path))):
                if isinstance(node, ast.Import):
                    names = [a.name for a in node.names]
                elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                    names = [node.module]
                else:
                    continue
                graph[package] |= {n.split(".")[0] for n in names} & set(PACKAGES) - {package}
    return graph


def test_the_architecture_picture_is_the_import_graph() -> None:
    drawn = {}
    for line in _block("imports"):
        src, _, dst = line.partition("->")
        drawn[src.strip()] = {d.strip() for d in dst.split(",") if d.strip()}
    assert drawn == package_graph()


def test_the_graph_sees_a_new_arrow(tmp_path: Path) -> None:
    for p in PACKAGES:
        (tmp_path / p).mkdir()
    (tmp_path / "firmware_logic" / "x.py").write_text("def f():\n    import bridge.cli\n")
    assert package_graph(tmp_path)["firmware_logic"] == {"bridge"}


def test_one_tick_is_followed_through_at_most_eight_files() -> None:
    files = [line.split()[0] for line in _block("tick")]
    assert len(files) <= 8
    assert [f for f in files if not (ROOT / f).is_file()] == []
