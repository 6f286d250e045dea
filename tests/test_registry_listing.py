"""The built-in behaviours' listing finds a folder as soon as it holds the
two files, and forgets one as soon as it lacks one (nothing is cached that
could go stale), and a Behaviour looks its robot class up once."""

from __future__ import annotations

from sim_backend import registry


def test_builtin_listing_follows_the_folder(tmp_path, monkeypatch):
    monkeypatch.setattr(registry, "BEHAVIOURS_DIR", tmp_path)
    for name, files in (("a", ("__init__.py", "spec.py")), ("b", ("__init__.py",)),
                        ("__pycache__", ())):
        (tmp_path / name).mkdir()
        for f in files:
            (tmp_path / name / f).write_text("")
    (tmp_path / "c.py").write_text("")
    assert registry.builtin() == {"a": "firmware_logic.behaviours.a"}
    (tmp_path / "b" / "spec.py").write_text("")
    assert registry.builtin() == {"a": "firmware_logic.behaviours.a",
                                  "b": "firmware_logic.behaviours.b"}
    (tmp_path / "a" / "spec.py").unlink()
    assert registry.builtin() == {"b": "firmware_logic.behaviours.b"}


def test_robot_class_is_looked_up_once_per_behaviour():
    b = registry.load("thesis")
    from firmware_logic.behaviours.thesis import robot
    assert b.robot_module is robot and b.robot_class is getattr(robot, b.package.ROBOT.split(":")[1])
    assert "robot_class" in vars(b) and "robot_module" in vars(b)     # kept on the instance
    assert registry.load("thesis").make_robot(0, 1, _scenario()).__class__ is b.robot_class


def _scenario():
    from sim_backend.scenario import Scenario
    return Scenario()
