"""The firmware subset checker: every rule rejects a small bad snippet at the
right line, the exemptions hold, and the real firmware passes."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from bridge.firmware.subset_check import (RULES, Violation, check_package, check_paths, firmware_files,
                                          package_dir)

DOCS = Path(__file__).resolve().parents[1] / "docs" / "subset.md"


def check(tmp_path: Path, source: str) -> set[tuple[str, int]]:
    f = tmp_path / "mod.py"
    f.write_text(textwrap.dedent(source).lstrip("\n"))
    return {(v.rule, v.line) for v in check_paths([f])}


# (rule, snippet, line of the violation); each snippet breaks exactly one rule
BAD = [
    ("FW-SYNTAX", "def f(:\n    pass\n", 1),
    ("FW-IMPORT", "import os\n", 1),
    ("FW-IMPORT", "X = 1\nfrom struct import pack\n", 2),
    ("FW-IMPORT", "import firmware_logicx\n", 1),
    ("FW-IMPORT", "def setup_f():\n    return __import__('os')\n", 2),
    ("FW-PRINT", "def setup_f(a):\n    print(a)\n", 2),
    ("FW-FLOAT", "X = 1\nY = 0.5\n", 2),
    ("FW-FLOAT", "X = 2j\n", 1),
    ("FW-FLOAT", "def setup_f(a):\n    return float(a)\n", 2),
    ("FW-DIV", "def f(a):\n    return a / 2\n", 2),
    ("FW-DIV", "def f(a):\n    a /= 2\n    return a\n", 2),
    ("FW-RECURSION", """
        def f(n):
            if n:
                return f(n - 1)
            return 0
        """, 3),
    ("FW-RECURSION", """
        class A:
            def walk(self, n):
                if n:
                    self.walk(n - 1)
        """, 4),
    ("FW-GENERATOR", "def f(n):\n    yield n\n", 2),
    ("FW-GENERATOR", "def f(n):\n    yield from n\n", 2),
    ("FW-ASYNC", "async def f():\n    return 0\n", 1),
    ("FW-LAMBDA", "F = lambda x: x\n", 1),
    ("FW-COMPREHENSION", "T = [1]\nL = [i for i in T]\n", 2),
    ("FW-COMPREHENSION", "def setup_f(t):\n    return {i for i in t}\n", 2),
    ("FW-COMPREHENSION", "def setup_f(t):\n    return {i: i for i in t}\n", 2),
    ("FW-COMPREHENSION", "def f(t):\n    return sum(i for i in t)\n", 2),
    ("FW-FSTRING", "def setup_f(a):\n    return f'{a}'\n", 2),
    ("FW-VARARGS", "def f(a, *args):\n    return a\n", 1),
    ("FW-VARARGS", "def f(a,\n      **kw):\n    return a\n", 2),
    ("FW-VARARGS", "def f(g, a):\n    return g(\n        *a)\n", 3),
    ("FW-VARARGS", "def f(g, a):\n    return g(**a)\n", 2),
    ("FW-GLOBAL", "X = 0\ndef f():\n    global X\n    X = 1\n", 3),
    ("FW-GLOBAL", """
        def setup_f():
            x = 0
            def g():
                nonlocal x
                x = 1
            g()
            return x
        """, 4),
    ("FW-SETUP", "SUBSET_SETUP = ('nothere',)\n", 1),
    ("FW-SETUP", "def f():\n    return 0\nSUBSET_SETUP = ['f']\n", 3),
    ("STEP-DISPLAY", "def f():\n    return [1]\n", 2),
    ("STEP-DISPLAY", "def f():\n    return {}\n", 2),
    ("STEP-DISPLAY", "def f(a):\n    return {a}\n", 2),
    ("STEP-TUPLE", "def f(a):\n    return a, 1\n", 2),
    ("STEP-TUPLE", "class A:\n    def m(self, a):\n        self.t = (1, a)\n", 3),
    ("STEP-SLICE", "def f(a):\n    return a[1:]\n", 2),
    ("STEP-FORMAT", "def f(a):\n    return 'n=%d' % a\n", 2),
    ("STEP-FORMAT", "def f(a):\n    return 'n=' + a\n", 2),
    ("STEP-FORMAT", "def f(a):\n    return '{}'.format(a)\n", 2),
    ("STEP-TRY", "def f(a):\n    try:\n        return a\n    except ValueError:\n        return 0\n", 2),
    ("STEP-WITH", "def f(a):\n    with a:\n        return 1\n", 2),
    ("STEP-CLOSURE", "def f(a):\n    def g():\n        return a\n    return g()\n", 2),
    ("STEP-CLOSURE", "def f():\n    class C:\n        pass\n    return C\n", 2),
]


@pytest.mark.parametrize("rule,source,line", BAD, ids=[f"{r}-{i}" for i, (r, _, _) in enumerate(BAD)])
def test_rule_rejects_snippet(tmp_path: Path, rule: str, source: str, line: int) -> None:
    assert check(tmp_path, source) == {(rule, line)}


def test_every_rule_has_a_bad_snippet() -> None:
    assert {r for r, _, _ in BAD} == set(RULES)


def test_indirect_recursion_reported_on_each_call_of_the_cycle(tmp_path: Path) -> None:
    found = check(tmp_path, """
        def f(n):
            return g(n)

        def g(n):
            if n:
                return f(n - 1)
            return 0

        class A:
            def a(self):
                return self.b()

            def b(self):
                return self.a()
        """)
    assert found == {("FW-RECURSION", 2), ("FW-RECURSION", 6),
                     ("FW-RECURSION", 11), ("FW-RECURSION", 14)}


GOOD = """
    from firmware_logic import fixedpoint as fx
    from firmware_logic.rng import Rng
    from . import messages
    import firmware_logic.hal

    TABLE = (1, -2, (3, 4), None, "s")
    LISTED = [1, 2]                     # module level: not the step path
    SUBSET_SETUP = ("build", "Host", "Robot.dump")


    def step(a, b, buf):
        a, b = b, a                     # compiled to stack rotations
        a, b, c = b, a, 7
        x = (1, -2, (3, 4))             # constant tuple
        for p in LISTED:
            a += p
        buf[0] = a // 2 + fx.ONE
        if a < 0:
            raise ValueError("bad %d %d" % (a, b))   # raise: exempt
        return x[0] + c


    def build(n):
        return [0] * n


    def setup_table(n):
        return (n, [n], {n: n})


    class Host:
        def plan(self, a):
            return [a]


    class Robot:
        LIMITS = (1, 2)

        def __init__(self, n):
            self.buf = [0] * n
            self.pair = (n, n)

        def step(self, hal):
            self.buf[0] = hal.x()
            return self.helper(self.buf)

        def helper(self, buf):
            return buf[0]

        def dump(self):
            return "%d %d" % (self.buf[0], self.buf[1])
    """


def test_exemptions_and_allowed_constructs(tmp_path: Path) -> None:
    assert check(tmp_path, GOOD) == set()


def test_violation_format() -> None:
    v = Violation("firmware_logic/behaviours/thesis/robot.py", 12, "STEP-TUPLE", "tuple of non-constants")
    assert str(v) == "firmware_logic/behaviours/thesis/robot.py:12: STEP-TUPLE tuple of non-constants"


def test_check_paths_accepts_directories(tmp_path: Path) -> None:
    (tmp_path / "a.py").write_text("import os\n")
    (tmp_path / "b.py").write_text("X = 1.0\n")
    found = check_paths([tmp_path])
    assert [(Path(v.path).name, v.line, v.rule) for v in found] == [
        ("a.py", 1, "FW-IMPORT"), ("b.py", 1, "FW-FLOAT")]


# every module in firmware_logic/, listed here and not through the checker's
# own file walk, so that no exemption can hide one: the folder holds only what
# may run on a robot (host code lives in sim_backend/, e.g. the registry);
# board_main.py alone is exempt, the board's MicroPython shell
FIRMWARE_MODULES = sorted(str(p.relative_to(package_dir())) for p in package_dir().rglob("*.py")
                          if "__pycache__" not in p.parts)


def test_only_the_board_shell_is_exempt() -> None:
    assert "board_main.py" in FIRMWARE_MODULES
    assert [m for m in FIRMWARE_MODULES if Path(m) not in
            {f.relative_to(package_dir()) for f in firmware_files(package_dir())}] == ["board_main.py"]


@pytest.mark.parametrize("module", [m for m in FIRMWARE_MODULES if m != "board_main.py"])
def test_every_firmware_module_is_in_the_subset(module: str) -> None:
    found = check_paths([package_dir() / module])
    assert found == [], "\n".join(str(v) for v in found)


def test_real_firmware_passes() -> None:
    """Every firmware_logic/*.py, as `touchswarm firmware check` sees it."""
    found = check_package()
    assert found == [], "\n".join(str(v) for v in found)


def test_docs_explain_every_rule() -> None:
    text = DOCS.read_text(encoding="utf-8")
    missing = [rule for rule in RULES if rule not in text]
    assert not missing
