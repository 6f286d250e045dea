"""AST checker for the MicroPython subset the robot firmware is written in.

Every rule, and why it exists, is documented in docs/subset.md. Two scopes:

- FW-* rules hold everywhere in firmware_logic/*.py (module level included):
  they keep the code portable between CPython and MicroPython and keep
  every result bit-identical on both.
- STEP-* rules hold only in the *step path*: every function and method except
  `__init__`, functions whose name starts with `setup_`, and names listed in
  a module-level tuple `SUBSET_SETUP = ("name", "Class", "Class.method", ...)`.
  Module-level and class-level code are not step path. They forbid
  constructs that allocate on the MicroPython heap on every call. Code inside
  a `raise` statement is exempt from STEP-* rules: raising allocates the
  exception anyway, and the step path must not raise in steady state.

Usage: `check_paths(paths)` or `check_package()`; each returns a sorted list
of `Violation`, printed as `path:line: RULE-ID message`.
"""

from __future__ import annotations

import ast
import logging
import os
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

log = logging.getLogger(__name__)

PACKAGE = "firmware_logic"
SETUP_TUPLE = "SUBSET_SETUP"
SETUP_PREFIX = "setup_"

# rule id -> one-line summary (docs/subset.md explains each)
RULES: dict[str, str] = {
    "FW-SYNTAX": "the file must parse",
    "FW-IMPORT": "imports only from firmware_logic (absolute or relative)",
    "FW-PRINT": "no print",
    "FW-FLOAT": "no float or complex literals, no float()/complex()",
    "FW-DIV": "no true division / or /= (use //)",
    "FW-RECURSION": "no recursion (direct or through other functions/methods)",
    "FW-GENERATOR": "no generators (yield / yield from)",
    "FW-ASYNC": "no async def / await / async for / async with",
    "FW-LAMBDA": "no lambda",
    "FW-COMPREHENSION": "no list/set/dict comprehensions or generator expressions",
    "FW-FSTRING": "no f-strings",
    "FW-VARARGS": "no *args/**kwargs in definitions, no * / ** unpacking in calls",
    "FW-GLOBAL": "no global / nonlocal",
    "FW-SETUP": "SUBSET_SETUP must be a module-level tuple of string literals naming "
                "functions, classes or Class.method of the module",
    "STEP-DISPLAY": "no list/dict/set displays in the step path",
    "STEP-TUPLE": "no non-constant tuple displays in the step path",
    "STEP-SLICE": "no slicing in the step path",
    "STEP-FORMAT": "no string formatting or concatenation in the step path",
    "STEP-TRY": "no try statements in the step path",
    "STEP-WITH": "no with statements in the step path",
    "STEP-CLOSURE": "no nested def/class inside step-path functions",
}


@dataclass(frozen=True, order=True)
class Violation:
    path: str
    line: int
    rule: str
    message: str

    def __str__(self) -> str:
        return "%s:%d: %s %s" % (self.path, self.line, self.rule, self.message)

    def as_dict(self) -> dict[str, object]:
        return {"path": self.path, "line": self.line, "rule": self.rule,
                "message": self.message}


_Func = (ast.FunctionDef, ast.AsyncFunctionDef)
_Comprehensions = {
    ast.ListComp: "list comprehension",
    ast.SetComp: "set comprehension",
    ast.DictComp: "dict comprehension",
    ast.GeneratorExp: "generator expression",
}


def _is_constant(node: ast.expr) -> bool:
    """True for what MicroPython compiles to a constant object (no allocation)."""
    if isinstance(node, ast.Constant):
        return True
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd, ast.Invert)):
        return isinstance(node.operand, ast.Constant) and isinstance(
            node.operand.value, int)
    if isinstance(node, ast.Tuple):
        return all(_is_constant(e) for e in node.elts)
    return False


def _is_str(node: ast.expr) -> bool:
    return (isinstance(node, ast.Constant) and isinstance(node.value, str)) or isinstance(
        node, ast.JoinedStr)


def _read_setup(tree: ast.Module) -> tuple[set[str], list[tuple[int, str]]]:
    """The names in SUBSET_SETUP, and problems with the tuple itself."""
    names: set[str] = set()
    problems: list[tuple[int, str]] = []
    defined: set[str] = set()
    node: ast.AST
    for node in tree.body:
        if isinstance(node, _Func):
            defined.add(node.name)
        elif isinstance(node, ast.ClassDef):
            defined.add(node.name)
            for item in node.body:
                if isinstance(item, _Func):
                    defined.add("%s.%s" % (node.name, item.name))
    for node in ast.walk(tree):
        target: ast.expr | None = None
        value: ast.expr | None = None
        if isinstance(node, ast.Assign) and len(node.targets) == 1:
            target, value = node.targets[0], node.value
        elif isinstance(node, ast.AnnAssign):
            target, value = node.target, node.value
        if not (isinstance(target, ast.Name) and target.id == SETUP_TUPLE):
            continue
        if node not in tree.body:
            problems.append((node.lineno, "%s must be assigned at module level" % SETUP_TUPLE))
            continue
        if not isinstance(value, ast.Tuple) or not all(
                isinstance(e, ast.Constant) and isinstance(e.value, str) for e in value.elts):
            problems.append((node.lineno, "%s must be a tuple of string literals" % SETUP_TUPLE))
            continue
        for e in value.elts:
            assert isinstance(e, ast.Constant)
            name = str(e.value)
            if name not in defined:
                problems.append((e.lineno, "%s names %r, which this module does not define"
                                 % (SETUP_TUPLE, name)))
            names.add(name)
    return names, problems


class _Checker(ast.NodeVisitor):
    def __init__(self, setup: set[str]) -> None:
        self.setup = setup
        self.found: list[tuple[int, str, str]] = []
        self.step = False          # inside a step-path function
        self.func_depth = 0
        self.class_stack: list[str] = []
        self.raise_depth = 0
        self.fstring_depth = 0
        self.swap_ok: set[int] = set()   # ids of RHS tuples of `a, b = b, a`

    # -- helpers -----------------------------------------------------------

    def report(self, node: ast.AST, rule: str, message: str) -> None:
        self.found.append((getattr(node, "lineno", 1), rule, message))

    @property
    def step_rules(self) -> bool:
        return self.step and not self.raise_depth

    def _exempt(self, name: str) -> bool:
        if name == "__init__" or name.startswith(SETUP_PREFIX) or name in self.setup:
            return True
        if self.class_stack:
            cls = self.class_stack[-1]
            return cls in self.setup or "%s.%s" % (cls, name) in self.setup
        return False

    def _check_arguments(self, args: ast.arguments) -> None:
        if args.vararg is not None:
            self.report(args.vararg, "FW-VARARGS", "*%s in a definition" % args.vararg.arg)
        if args.kwarg is not None:
            self.report(args.kwarg, "FW-VARARGS", "**%s in a definition" % args.kwarg.arg)

    # -- definitions -------------------------------------------------------

    def _function(self, node: ast.FunctionDef | ast.AsyncFunctionDef) -> None:
        self._check_arguments(node.args)
        # decorators and defaults run where the def runs
        for d in node.decorator_list:
            self.visit(d)
        self.visit(node.args)
        if node.returns is not None:
            self.visit(node.returns)
        saved = self.step
        if self.func_depth == 0:
            self.step = not self._exempt(node.name)
        elif self.step and not self.raise_depth:
            self.report(node, "STEP-CLOSURE",
                        "nested def %s creates a function object on every call" % node.name)
        self.func_depth += 1
        for stmt in node.body:
            self.visit(stmt)
        self.func_depth -= 1
        self.step = saved

    def visit_FunctionDef(self, node: ast.FunctionDef) -> None:
        self._function(node)

    def visit_AsyncFunctionDef(self, node: ast.AsyncFunctionDef) -> None:
        self.report(node, "FW-ASYNC", "async def %s" % node.name)
        self._function(node)

    def visit_ClassDef(self, node: ast.ClassDef) -> None:
        if self.func_depth and self.step_rules:
            self.report(node, "STEP-CLOSURE",
                        "class %s defined inside a step-path function" % node.name)
        for d in node.decorator_list:
            self.visit(d)
        for b in node.bases:
            self.visit(b)
        for k in node.keywords:
            self.visit(k)
        saved = self.step
        if self.func_depth == 0:
            self.step = False      # the class body runs once, at import
        self.class_stack.append(node.name)
        for stmt in node.body:
            self.visit(stmt)
        self.class_stack.pop()
        self.step = saved

    def visit_Lambda(self, node: ast.Lambda) -> None:
        self.report(node, "FW-LAMBDA", "lambda")
        self._check_arguments(node.args)
        self.generic_visit(node)

    # -- statements --------------------------------------------------------

    def visit_Import(self, node: ast.Import) -> None:
        for alias in node.names:
            if alias.name != PACKAGE and not alias.name.startswith(PACKAGE + "."):
                self.report(node, "FW-IMPORT", "import %s (only %s is importable)"
                            % (alias.name, PACKAGE))

    def visit_ImportFrom(self, node: ast.ImportFrom) -> None:
        mod = node.module or ""
        if node.level == 0 and mod != PACKAGE and not mod.startswith(PACKAGE + "."):
            self.report(node, "FW-IMPORT", "from %s import ... (only %s is importable)"
                        % (mod, PACKAGE))

    def visit_Global(self, node: ast.Global) -> None:
        self.report(node, "FW-GLOBAL", "global %s" % ", ".join(node.names))

    def visit_Nonlocal(self, node: ast.Nonlocal) -> None:
        self.report(node, "FW-GLOBAL", "nonlocal %s" % ", ".join(node.names))

    def visit_Raise(self, node: ast.Raise) -> None:
        self.raise_depth += 1
        self.generic_visit(node)
        self.raise_depth -= 1

    def visit_Try(self, node: ast.AST) -> None:
        if self.step_rules:
            self.report(node, "STEP-TRY", "try statement in the step path")
        self.generic_visit(node)

    visit_TryStar = visit_Try

    def visit_With(self, node: ast.With) -> None:
        if self.step_rules:
            self.report(node, "STEP-WITH", "with statement in the step path")
        self.generic_visit(node)

    def visit_AsyncWith(self, node: ast.AsyncWith) -> None:
        self.report(node, "FW-ASYNC", "async with")
        self.visit_With(node)  # type: ignore[arg-type]

    def visit_AsyncFor(self, node: ast.AsyncFor) -> None:
        self.report(node, "FW-ASYNC", "async for")
        self.generic_visit(node)

    def visit_Assign(self, node: ast.Assign) -> None:
        # MicroPython compiles `a, b = c, d` (and the 3-element form) to stack
        # rotations without building a tuple
        if len(node.targets) == 1:
            t, v = node.targets[0], node.value
            if (isinstance(t, ast.Tuple) and isinstance(v, ast.Tuple)
                    and len(t.elts) == len(v.elts) and len(v.elts) in (2, 3)
                    and not any(isinstance(e, ast.Starred) for e in t.elts + v.elts)):
                self.swap_ok.add(id(v))
        self.generic_visit(node)

    def visit_AugAssign(self, node: ast.AugAssign) -> None:
        if isinstance(node.op, ast.Div):
            self.report(node, "FW-DIV", "true division /= (use //=)")
        if self.step_rules and isinstance(node.op, (ast.Add, ast.Mod)) and _is_str(node.value):
            self.report(node, "STEP-FORMAT", "string concatenation/formatting allocates")
        self.generic_visit(node)

    # -- expressions -------------------------------------------------------

    def visit_Constant(self, node: ast.Constant) -> None:
        if isinstance(node.value, float):
            self.report(node, "FW-FLOAT", "float literal %r" % node.value)
        elif isinstance(node.value, complex):
            self.report(node, "FW-FLOAT", "complex literal %r" % node.value)

    def visit_Name(self, node: ast.Name) -> None:
        if node.id == "print":
            self.report(node, "FW-PRINT", "print (use the HAL or the trace)")
        elif node.id in ("float", "complex"):
            self.report(node, "FW-FLOAT", "%s()" % node.id)
        elif node.id == "__import__":
            self.report(node, "FW-IMPORT", "__import__")

    def visit_BinOp(self, node: ast.BinOp) -> None:
        if isinstance(node.op, ast.Div):
            self.report(node, "FW-DIV", "true division / (use //)")
        if self.step_rules:
            if isinstance(node.op, ast.Mod) and _is_str(node.left):
                self.report(node, "STEP-FORMAT", "%-formatting builds a new string")
            elif isinstance(node.op, ast.Add) and (_is_str(node.left) or _is_str(node.right)):
                self.report(node, "STEP-FORMAT", "string concatenation builds a new string")
        self.generic_visit(node)

    def visit_Call(self, node: ast.Call) -> None:
        for a in node.args:
            if isinstance(a, ast.Starred):
                self.report(a, "FW-VARARGS", "* unpacking in a call")
        for k in node.keywords:
            if k.arg is None:
                self.report(k.value, "FW-VARARGS", "** unpacking in a call")
        if (self.step_rules and isinstance(node.func, ast.Attribute)
                and node.func.attr == "format"):
            self.report(node, "STEP-FORMAT", ".format() builds a new string")
        self.generic_visit(node)

    def visit_JoinedStr(self, node: ast.JoinedStr) -> None:
        if not self.fstring_depth:
            self.report(node, "FW-FSTRING", "f-string (MicroPython rewrites it to str.format; "
                        "use %-formatting outside the step path)")
        self.fstring_depth += 1
        self.generic_visit(node)
        self.fstring_depth -= 1

    def visit_Yield(self, node: ast.Yield) -> None:
        self.report(node, "FW-GENERATOR", "yield makes a generator")
        self.generic_visit(node)

    def visit_YieldFrom(self, node: ast.YieldFrom) -> None:
        self.report(node, "FW-GENERATOR", "yield from makes a generator")
        self.generic_visit(node)

    def visit_Await(self, node: ast.Await) -> None:
        self.report(node, "FW-ASYNC", "await")
        self.generic_visit(node)

    def _comprehension(self, node: ast.AST) -> None:
        self.report(node, "FW-COMPREHENSION", _Comprehensions[type(node)])
        self.generic_visit(node)

    visit_ListComp = _comprehension
    visit_SetComp = _comprehension
    visit_DictComp = _comprehension
    visit_GeneratorExp = _comprehension

    def visit_List(self, node: ast.List) -> None:
        if self.step_rules and isinstance(node.ctx, ast.Load):
            self.report(node, "STEP-DISPLAY", "list display allocates a list")
        self.generic_visit(node)

    def visit_Dict(self, node: ast.Dict) -> None:
        if self.step_rules:
            self.report(node, "STEP-DISPLAY", "dict display allocates a dict")
        self.generic_visit(node)

    def visit_Set(self, node: ast.Set) -> None:
        if self.step_rules:
            self.report(node, "STEP-DISPLAY", "set display allocates a set")
        self.generic_visit(node)

    def visit_Tuple(self, node: ast.Tuple) -> None:
        if (self.step_rules and isinstance(node.ctx, ast.Load)
                and id(node) not in self.swap_ok and not _is_constant(node)):
            self.report(node, "STEP-TUPLE", "tuple of non-constants allocates a tuple")
        self.generic_visit(node)

    def visit_Slice(self, node: ast.Slice) -> None:
        if self.step_rules:
            self.report(node, "STEP-SLICE", "slicing allocates a slice and a copy")
        self.generic_visit(node)


def _self_name(fn: ast.FunctionDef | ast.AsyncFunctionDef) -> str | None:
    for d in fn.decorator_list:
        if isinstance(d, ast.Name) and d.id in ("staticmethod", "classmethod"):
            return None
    args = fn.args.posonlyargs + fn.args.args
    return args[0].arg if args else None


def _recursion(tree: ast.Module) -> list[tuple[int, str, str]]:
    """Calls that close a cycle in the module's call graph.

    Nodes are module functions (called by name) and, per class, methods
    (called as self.<name>). Each edge that lies on a cycle is reported at
    the call's line.
    """
    # node key -> list of (callee key, line)
    edges: dict[str, list[tuple[str, int]]] = {}
    funcs = {n.name: n for n in tree.body if isinstance(n, _Func)}
    for name, fn in funcs.items():
        out = edges.setdefault(name, [])
        for c in ast.walk(fn):
            if isinstance(c, ast.Call) and isinstance(c.func, ast.Name) and c.func.id in funcs:
                out.append((c.func.id, c.lineno))
    for cls in tree.body:
        if not isinstance(cls, ast.ClassDef):
            continue
        methods = {n.name: n for n in cls.body if isinstance(n, _Func)}
        for name, fn in methods.items():
            key = "%s.%s" % (cls.name, name)
            out = edges.setdefault(key, [])
            me = _self_name(fn)
            for c in ast.walk(fn):
                if not isinstance(c, ast.Call):
                    continue
                f = c.func
                if (me is not None and isinstance(f, ast.Attribute)
                        and isinstance(f.value, ast.Name) and f.value.id == me
                        and f.attr in methods):
                    out.append(("%s.%s" % (cls.name, f.attr), c.lineno))
                elif isinstance(f, ast.Name) and f.id in funcs:
                    out.append((f.id, c.lineno))

    def path_back(start: str, goal: str) -> list[str] | None:
        """Shortest call path start -> ... -> goal, or None."""
        prev: dict[str, str | None] = {start: None}
        queue = [start]
        while queue:
            cur = queue.pop(0)
            if cur == goal:
                chain = [cur]
                while prev[chain[-1]] is not None:
                    chain.append(prev[chain[-1]])  # type: ignore[arg-type]
                return chain[::-1]
            for nxt, _ in edges.get(cur, ()):
                if nxt not in prev:
                    prev[nxt] = cur
                    queue.append(nxt)
        return None

    found: list[tuple[int, str, str]] = []
    for caller, calls in edges.items():
        for callee, line in calls:
            if callee == caller:
                found.append((line, "FW-RECURSION", "%s calls itself" % caller))
                continue
            back = path_back(callee, caller)
            if back is not None:
                found.append((line, "FW-RECURSION", "%s -> %s (indirect recursion)"
                              % (caller, " -> ".join(back))))
    return found


def check_source(source: str, path: str) -> list[Violation]:
    """Violations in one module's source text; `path` is used for reporting."""
    try:
        tree = ast.parse(source, filename=path)
    except SyntaxError as e:
        return [Violation(path, e.lineno or 1, "FW-SYNTAX", str(e.msg))]
    setup, problems = _read_setup(tree)
    checker = _Checker(setup)
    checker.visit(tree)
    found = checker.found + _recursion(tree)
    found += [(line, "FW-SETUP", message) for line, message in problems]
    return sorted({Violation(path, line, rule, message) for line, rule, message in found})


def _display(path: Path) -> str:
    try:
        return os.path.relpath(path)
    except ValueError:
        return str(path)


def check_paths(paths: Iterable[str | os.PathLike[str]]) -> list[Violation]:
    """Check the given files (directories: their *.py files)."""
    out: list[Violation] = []
    for p in paths:
        path = Path(p)
        files = firmware_files(path) if path.is_dir() else [path]
        for f in files:
            shown = _display(f)
            log.debug("subset check %s", shown)
            out.extend(check_source(f.read_text(encoding="utf-8"), shown))
    return sorted(out)


# the one module inside firmware_logic/ outside the subset's rules (every
# other one may run on a robot; host code lives in sim_backend/, e.g. the
# behaviour registry): board_main.py is the board's main.py,
# the MicroPython shell round the firmware (it opens the port, reads
# robot_config and imports the behaviour: sys, select, __import__), checked by
# mpy-cross at deploy and run on the unix port by the HIL tests
BOARD_SHELL = ("board_main.py",)


def firmware_files(root: Path) -> list[Path]:
    """Every firmware module under root, behaviour packages included."""
    return sorted(p for p in root.rglob("*.py")
                  if p.name not in BOARD_SHELL and "__pycache__" not in p.parts)


def package_dir() -> Path:
    """The directory of the firmware_logic package."""
    import firmware_logic

    return Path(firmware_logic.__file__).resolve().parent


def check_package() -> list[Violation]:
    """Check every firmware_logic/*.py."""
    return check_paths([package_dir()])
