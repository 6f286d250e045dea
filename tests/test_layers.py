"""The layers read top-down (issue 27 item 3): the world (sim_backend/) and
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
