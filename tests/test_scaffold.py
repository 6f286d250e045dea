"""`touchswarm behaviour new NAME`: the copy speaks of NAME, not of the
template (its TITLE and module docstrings), its robot's code keeps the
template's line numbers (so its soa step is the template's compiled one), and
it refuses, in one line suggesting --into, a folder inside an installed
package or one it cannot write."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from bridge.cli import main
from bridge.commands import behaviours
from sim_backend import registry

TEMPLATE = registry.load("aggregate").folder


def module_doc(path: Path) -> str:
    return ast.get_docstring(ast.parse(path.read_text())) or ""


def test_the_copy_has_its_own_title_and_docstrings(tmp_path: Path, capsys) -> None:
    assert main(["behaviour", "new", "tidy", "--into", str(tmp_path)]) == 0
    folder = tmp_path / "tidy"
    b = registry.load(str(folder))
    assert b.spec.TITLE.startswith("tidy: ") and b.spec.TITLE != registry.load("aggregate").spec.TITLE
    for file in ("spec.py", "robot.py", "coordinator.py", "__init__.py"):
        doc = module_doc(folder / file)
        assert doc.startswith("tidy"), (file, doc)
        assert "ggregation" not in doc, (file, doc)
        assert module_doc(TEMPLATE / file) != doc
    # below its docstring the robot is the template's, line for line
    assert (folder / "robot.py").read_text().splitlines()[5:] \
        == (TEMPLATE / "robot.py").read_text().splitlines()[5:]
    assert ast.parse((folder / "robot.py").read_text()).body[1].lineno \
        == ast.parse((TEMPLATE / "robot.py").read_text()).body[1].lineno


def refused(capsys, argv: list[str], *needles: str) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    for n in needles:
        assert n in err, err


def test_site_packages_is_refused(tmp_path: Path, capsys) -> None:
    inside = tmp_path / "lib" / "site-packages" / "firmware_logic" / "behaviours"
    inside.mkdir(parents=True)
    refused(capsys, ["behaviour", "new", "tidy", "--into", str(inside)],
            "site-packages", "--into DIR")
    assert not (inside / "tidy").exists()


def test_the_default_folder_is_refused_when_installed(tmp_path: Path, capsys,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    # an installed (non-editable) touchswarm: the built-ins' folder is in site-packages
    monkeypatch.setattr(behaviours.sysconfig, "get_paths",
                        lambda: {"purelib": str(TEMPLATE.parent), "platlib": str(tmp_path)})
    refused(capsys, ["behaviour", "new", "tidy"], "installed package", "--into DIR")
    assert not (TEMPLATE.parent / "tidy").exists()


def test_a_folder_not_writable_is_refused(tmp_path: Path, capsys,
                                          monkeypatch: pytest.MonkeyPatch) -> None:
    # root writes anywhere: os.access stands in for a read-only folder
    monkeypatch.setattr(behaviours.os, "access", lambda path, mode: False)
    refused(capsys, ["behaviour", "new", "tidy", "--into", str(tmp_path)],
            "not writable", "--into DIR")
    assert not (tmp_path / "tidy").exists()
