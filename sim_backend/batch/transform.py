"""Source transform of firmware-subset code into struct-of-arrays functions.

The batch engine does not compile the robots' classes as they are (numba
jitclass instances are reference-counted on every method call and attribute
read, and cannot be cached on disk); this module rewrites the same
unmodified source instead:

- every class becomes arrays over all its instances: its ints, bools and
  instances of other classes (their indices into that class's arrays) one
  int32[n, fields] table (TABLE), lists of ints -> int64[n, len], numpy
  arrays of a class with one instance -> the array itself; the field
  types are read off the live CPython instances, which the CPython
  constructors build (so `__init__` is never transformed);
- every method reached from the entry points becomes a plain function
  `F_Cls_m(_soa, self, ...)`: `_soa` is one namedtuple holding every array,
  `self` (and any parameter holding an object) is the instance's index;
  `self.x` -> `_soa.Cls__x[self]`, `self.m(a)` -> `F_Cls_m(_soa, self, a)`;
- calls resolve statically: the type of every object-valued expression is
  known (a parameter's from its call sites, a field's from the instances),
  so the HAL the robot is handed is the batch body, with no dispatch left;
- module functions stay functions (with `_soa` first), module constants
  become literals or globals of the generated module.

Only what the entry points reach is transformed. A construct outside the
transform (a nested def, try, with, a list display, an object returned or
stored in a local that changes type, ...) is a CompileError naming it, its
file and line, never a silent mis-compilation. sim_backend/batch/soa.py
writes the generated source into a cache directory and compiles it with
`njit(cache=True)`.
"""

from __future__ import annotations

import ast
import builtins
import hashlib
import inspect
import operator
import os
import sys
import textwrap
from itertools import chain, repeat
from dataclasses import dataclass, field
from types import FunctionType, ModuleType
from typing import Any, Sequence

import numpy as np

from sim_backend.errors import CompileError

STATE = "_soa"                      # the state placeholder of every function
# part of the generated text, so a new borrow or inlining rule is a new cache entry
CODEGEN = "borrowed noalias entries, per-robot path inlined, prefetch, int32 tables"
BUILTINS = {"range", "len", "abs", "min", "max", "int", "bool"}
CONSTANT_TYPES = (bool, int, float, str, type(None))
# plain functions the generated code calls as borrow.py's numba intrinsic of
# the same name (an array, or a list of objects as its table, then ints); their
# Python body is what the uncompiled code runs. `prefetch` of an object and
# `prefetch_held` are spelt out as prefetches of rows (FunctionTransform.fetch_rows)
INTRINSICS = {"sim_backend.kernel.prefetch": "prefetch",
              "sim_backend.kernel.prefetch_held": "prefetch_held",
              "sim_backend.kernel.clear": "clear"}


# -- kinds of values -------------------------------------------------------------

@dataclass(frozen=True)
class Inst:
    """An object of class `cls`; the expression holding it is its index."""
    cls: type


@dataclass(frozen=True)
class ListOf:
    """A list of every instance of `cls`, in index order (the robots)."""
    cls: type


@dataclass(frozen=True)
class Row:
    """A list-of-ints field of one instance: `arr` is the 2-D array's name."""
    arr: str
    index: ast.expr = field(compare=False, hash=False)


SCALAR = "scalar"                    # anything the generated code passes through

# The element of every class's table of int, bool and object fields. A
# firmware-subset int lives in 31 bits (|x| < 2**30, firmware_logic/
# fixedpoint.py and rng.py): on a 32-bit board a wider one is a heap object
# (MicroPython's small int ends there), which the step's 0-heap rule forbids,
# so int32 holds every value a behaviour may keep, in half the bytes of int64 (the
# thesis robot's row: 172 bytes, three or four lines, not six or seven). The rule
# is enforced, not assumed: a start value outside int32 is refused at the
# build (state_arrays), and a store the transform does not prove to fit
# (`proven`) is checked when it runs (borrow.fits), a typed error, never a
# value wrapped round. List fields (message buffers the host fills) stay int64.
TABLE = np.int32
TABLE_LO, TABLE_HI = int(np.iinfo(TABLE).min), int(np.iinfo(TABLE).max)


def in_table(v: Any) -> bool:
    return isinstance(v, int) and TABLE_LO <= v <= TABLE_HI      # a bool is an int


# -- the layout: classes and their fields ------------------------------------------

@dataclass
class ClassLayout:
    cls: type
    name: str                                      # short name in generated code
    instances: list[Any] = field(default_factory=list)
    fields: dict[str, Any] = field(default_factory=dict)   # attr -> kind descriptor
    # kind descriptors: ("int",), ("bool",), ("row", length), ("array",), ("inst", cls)
    columns: dict[str, int] = field(default_factory=dict)  # int, bool, inst -> column
    bases: list[np.ndarray] = field(default_factory=list)  # arrays the array fields view
    views: dict[str, tuple[int, int]] = field(default_factory=dict)  # attr -> (base, row)

    def finish(self) -> None:
        """Where each field lives: ints, bools and object indices in one
        TABLE[n, columns] table (one instance's fields side by side); an array field that is row k of a bigger array
        as (that array, k), so a function takes the few base arrays, not
        dozens of rows."""
        self.columns.clear()
        self.bases.clear()
        self.views.clear()
        for attr, f in self.fields.items():
            if f[0] in ("int", "bool", "inst"):
                self.columns[attr] = len(self.columns)
            elif f[0] == "array":
                v = getattr(self.instances[0], attr)
                b = v.base
                if (isinstance(b, np.ndarray) and b.ndim == v.ndim + 1
                        and b.shape[1:] == v.shape and b.flags.c_contiguous
                        and v.flags.c_contiguous):
                    off = v.ctypes.data - b.ctypes.data
                    k, rem = divmod(off, b.strides[0])
                    if rem == 0 and 0 <= k < b.shape[0]:
                        j = next((n for n, x in enumerate(self.bases) if x is b), None)
                        if j is None:
                            j = len(self.bases)
                            self.bases.append(b)
                        self.views[attr] = (j, k)


class Layout:
    """Every instance reachable from the roots, numbered per class."""

    def __init__(self) -> None:
        self.classes: dict[type, ClassLayout] = {}
        self.index: dict[int, tuple[type, int]] = {}   # id(obj) -> (class, index)
        # per class, what an instance laid out by the full walk looked like:
        # (its field names, their exact types, the row fields' positions and
        # lengths, the instance fields' positions); an instance that looks
        # the same gets the same kinds, so a batch's 10,000 robots are checked
        # at C speed (one tuple comparison) instead of field by field
        self._seen: dict[type, tuple[tuple, tuple, tuple, tuple]] = {}

    def add(self, obj: Any) -> int:
        if id(obj) in self.index:
            return self.index[id(obj)][1]
        cls = type(obj)
        seen = self._seen.get(cls)
        if seen is not None:
            d = vars(obj)
            keys, types, rows, insts = seen
            values = tuple(d.values())
            if (tuple(d) == keys and tuple(map(type, values)) == types
                    and all(len(values[k]) == n and all(type(v) is int for v in values[k])
                            for k, n in rows)):
                cl = self.classes[cls]
                j = len(cl.instances)
                cl.instances.append(obj)
                self.index[id(obj)] = (cls, j)
                for k in insts:
                    self.add(values[k])
                return j
        j = self._add(obj, cls)
        if seen is None:
            d = vars(obj)
            kinds = [self.classes[cls].fields[a] for a in d]
            if all(k[0] != "array" for k in kinds):
                self._seen[cls] = (tuple(d), tuple(map(type, d.values())),
                                   tuple((k, f[1]) for k, f in enumerate(kinds) if f[0] == "row"),
                                   tuple(k for k, f in enumerate(kinds) if f[0] == "inst"))
        return j

    def add_all(self, objs: Sequence[Any]) -> None:
        """add(o) for every o in order, the same numbering and checks; a run
        of instances of one class already laid out (a batch's robots after
        the first) is checked and numbered in C-level passes over the whole
        list rather than one Python call per object and per object it holds:
        a third of a 250-run batch's layout walk."""
        if not objs:
            return
        self.add(objs[0])
        rest = objs[1:]
        if not self._bulk(rest):
            for o in rest:
                self.add(o)

    def _bulk(self, objs: Sequence[Any]) -> bool:
        """Lay out `objs` as add() would, one by one, or return False (having
        changed nothing) unless they are fresh, distinct instances of a class
        laid out before, each looking as its first instance did, whose object
        fields each hold a class of its own with no object fields: then
        add()'s depth-first order numbers every class's instances as list
        order does."""
        if not objs:
            return True
        cls = type(objs[0])
        seen = self._seen.get(cls)
        if seen is None or not all(type(o) is cls for o in objs):
            return False
        keys, types, rows, insts = seen
        targets = [types[k] for k in insts]
        if cls in targets or len(set(targets)) != len(targets) or any(
                self._seen.get(t, (0, 0, 0, (0,)))[3] for t in targets):
            return False
        index = self.index
        ids = list(map(id, objs))
        if any(map(index.__contains__, ids)) or len(set(ids)) != len(ids):
            return False
        dicts = list(map(vars, objs))
        if not all(map(keys.__eq__, map(tuple, dicts))):
            return False
        values: list[tuple] = list(map(tuple, map(operator.methodcaller("values"), dicts)))
        if not all(map(types.__eq__, map(tuple, map(map, repeat(type), values)))):
            return False
        for k, n in rows:
            lists = [v[k] for v in values]
            if not (all(map(n.__eq__, map(len, lists)))
                    and set(map(type, chain.from_iterable(lists))) <= {int}):
                return False
        held = [[v[k] for v in values] for k in insts]
        for group in held:              # fresh and distinct too, or add() decides
            gids = list(map(id, group))
            if any(map(index.__contains__, gids)) or len(set(gids)) != len(gids):
                return False
        cl = self.classes[cls]
        j = len(cl.instances)
        cl.instances.extend(objs)
        index.update(zip(ids, ((cls, k) for k in range(j, j + len(objs)))))
        for group in held:
            if not self._bulk(group):
                for o in group:
                    self.add(o)
        return True

    def values(self, cl: ClassLayout) -> dict[str, Sequence[Any]]:
        """Every field's values now, instance by instance: one C-level
        getter call per instance, not one getattr per field and instance."""
        names = list(cl.fields)
        if not names or not cl.instances or any("." in a for a in names):
            return {a: [getattr(o, a) for o in cl.instances] for a in names}
        get = operator.attrgetter(*names)
        if len(names) == 1:
            return {names[0]: list(map(get, cl.instances))}
        return dict(zip(names, zip(*map(get, cl.instances))))

    def _add(self, obj: Any, cls: type) -> int:
        cl = self.classes.get(cls)
        if cl is None:
            name = cls.__name__
            taken = {c.name for c in self.classes.values()}
            k = 2
            while name in taken:
                name = f"{cls.__name__}{k}"
                k += 1
            cl = self.classes[cls] = ClassLayout(cls, name)
        j = len(cl.instances)
        cl.instances.append(obj)
        self.index[id(obj)] = (cls, j)
        for attr, value in vars(obj).items():
            kind = self._kind(cls, attr, value)
            old = cl.fields.setdefault(attr, kind)
            if old != kind:
                raise CompileError(f"{cls.__name__}.{attr}: {old} in one instance, {kind} in "
                                   "another (the batch engine needs one type per field)")
        missing = set(cl.fields) - set(vars(obj))
        if missing:
            raise CompileError(f"{cls.__name__}.{sorted(missing)[0]}: set on some instances "
                               "only")
        return j

    def _kind(self, cls: type, attr: str, value: Any) -> tuple:
        if isinstance(value, bool):
            return ("bool",)
        if isinstance(value, int):
            return ("int",)
        if isinstance(value, list) and all(type(v) is int for v in value):
            return ("row", len(value))
        if isinstance(value, np.ndarray):
            if len(self.classes[cls].instances) > 1:
                raise CompileError(f"{cls.__name__}.{attr}: a numpy array field needs a "
                                   "class of one instance")
            return ("array",)
        if type(value).__module__ in ("builtins", "numpy") or isinstance(value, type):
            raise CompileError(f"{cls.__name__}.{attr}: a {type(value).__name__} is outside "
                               "the subset the batch engine compiles (ints, lists of ints, "
                               "objects of such classes)")
        self.add(value)
        return ("inst", type(value))

    def count(self, cls: type) -> int:
        return len(self.classes[cls].instances)


def array_name(cl: ClassLayout, attr: str) -> str:
    return f"{cl.name}__{attr}"


def ints_name(cl: ClassLayout) -> str:
    return f"{cl.name}__ints"


def base_name(cl: ClassLayout, j: int) -> str:
    return f"{cl.name}__base{j}"


def count_name(cl: ClassLayout) -> str:
    return f"{cl.name}__N"


# -- the transform ----------------------------------------------------------------------

def _err(fn: FunctionType, node: ast.AST | None, what: str) -> CompileError:
    line = fn.__code__.co_firstlineno + getattr(node, "lineno", 1) - 1
    return CompileError(f"{fn.__code__.co_filename}:{line}: {what} is outside what the "
                        "struct-of-arrays transform compiles")


def _modkey(name: str) -> str:
    return name.replace(".", "_")


@dataclass
class Spec:
    """One function specialised on the kinds of its object parameters."""
    fn: FunctionType
    owner: type | None
    kinds: tuple
    name: str


class Program:
    """The generated module: functions reached from the entry points."""

    def __init__(self, layout: Layout) -> None:
        self.layout = layout
        self.specs: dict[tuple, Spec] = {}
        self.done: dict[str, tuple[FunctionTransform, ast.FunctionDef]] = {}
        self.globals: dict[str, str] = {}        # generated global name -> literal source
        self.queue: list[Spec] = []
        self.names_used: set[str] = set()
        # what the generated text was read from (the cache's check, `Inputs`)
        self.files: set[str] = set()
        self.lookups: dict[tuple[str, ...], str] = {}

    def entry(self, fn: FunctionType, kinds: tuple) -> str:
        name = self.spec(fn, None, kinds)
        self._drain()
        return name

    def spec(self, fn: FunctionType, owner: type | None, kinds: tuple) -> str:
        key = (fn, owner, kinds)
        if key in self.specs:
            return self.specs[key].name
        base = "F_" + (f"{self.layout.classes[owner].name}_{fn.__name__}" if owner is not None
                       else f"{_modkey(fn.__module__)}__{fn.__name__}")
        name = base
        k = 2
        while name in self.names_used:
            name = f"{base}__{k}"
            k += 1
        self.names_used.add(name)
        s = Spec(fn, owner, kinds, name)
        self.specs[key] = s
        self.queue.append(s)
        return name

    def _drain(self) -> None:
        while self.queue:
            s = self.queue.pop(0)
            ft = FunctionTransform(self, s)
            self.done[s.name] = (ft, ft.build())

    def params(self) -> dict[str, list[str]]:
        """Per function, the state it uses with every function it calls, sorted:
        its leading parameters (a fixpoint over the call graph)."""
        uses = {name: set(ft.uses) for name, (ft, _) in self.done.items()}
        changed = True
        while changed:
            changed = False
            for name, (ft, _) in self.done.items():
                for callee in ft.calls:
                    if not uses[callee] <= uses[name]:
                        uses[name] |= uses[callee]
                        changed = True
        return {name: sorted(u) for name, u in uses.items()}

    def robot_path(self, entries: dict[str, tuple[FunctionType, tuple]]) -> set[str]:
        """The functions numba inlines (forceinline): those a robot's step
        reaches (its FSM, its HAL, the kernel's sensing), run once per robot
        per tick, and those that reach it (the entry's robot loop). In one
        function with the entry's borrowed arrays (borrow.py), LLVM sees every
        array's owner is null and drops the reference counting, and keeps a
        robot's row and the world's arrays in registers across the calls
        (docs/performance.md). The world's per-run functions stay calls:
        inlining them too only costs compile time."""
        robots = {k.cls for _, kinds in entries.values() for k in kinds if isinstance(k, ListOf)}
        steps = {s.name for s in self.specs.values() if s.owner in robots}
        todo = list(steps)
        seen: set[str] = set()
        while todo:
            name = todo.pop()
            if name not in seen:
                seen.add(name)
                todo += self.done[name][0].calls
        loops: set[str] = set()      # the functions that call a robot's methods, and theirs
        grew = True
        while grew:
            callers = {name for name, (ft, _) in self.done.items()
                       if name not in loops and name not in steps and ft.calls & (steps | loops)}
            loops |= callers
            grew = bool(callers)
        return seen | loops

    def render(self) -> list[tuple[str, str]]:
        """(origin comment, source) of every function, the state made parameters."""
        params = self.params()
        out = []
        for name, (ft, tree) in self.done.items():
            tree = _Bind(params).visit(tree)
            ast.fix_missing_locations(tree)
            out.append((ft.origin(), ast.unparse(tree)))
        return out

    def global_name(self, module: str, name: str, value: Any) -> str:
        g = f"G_{_modkey(module)}__{name}"
        if g not in self.globals:
            if isinstance(value, tuple) and all(isinstance(v, CONSTANT_TYPES) for v in value):
                self.globals[g] = repr(value)
            else:
                raise CompileError(f"{module}.{name}: a {type(value).__name__} constant is "
                                   "outside the subset (ints, strings, tuples of them)")
        return g


class _Bind(ast.NodeTransformer):
    """`_soa.X` -> `X`; the `_soa` parameter and argument -> the used arrays."""

    def __init__(self, params: dict[str, list[str]]) -> None:
        self.params = params

    def visit_FunctionDef(self, node: ast.FunctionDef) -> ast.FunctionDef:
        self.generic_visit(node)
        a = node.args.args
        node.args.args = [ast.arg(p) for p in self.params[node.name]] + a[1:]
        return node

    def visit_Attribute(self, node: ast.Attribute) -> ast.expr:
        if isinstance(node.value, ast.Name) and node.value.id == STATE:
            return ast.Name(node.attr, ast.Load())
        self.generic_visit(node)
        return node

    def visit_Call(self, node: ast.Call) -> ast.Call:
        self.generic_visit(node)
        if isinstance(node.func, ast.Name) and node.func.id in self.params:
            node.args = [ast.Name(p, ast.Load()) for p in self.params[node.func.id]] \
                + node.args[1:]
        return node


class FunctionTransform:
    def __init__(self, program: Program, spec: Spec) -> None:
        self.p = program
        self.s = spec
        self.fn = spec.fn
        self.glob = spec.fn.__globals__
        src = textwrap.dedent(inspect.getsource(spec.fn))
        program.files.add(spec.fn.__code__.co_filename)
        tree = ast.parse(src)
        node = tree.body[0]
        if not isinstance(node, ast.FunctionDef):
            raise _err(self.fn, node, "a decorated or non-plain function")
        self.node = node
        self.locals: dict[str, Any] = {}
        self.uses: set[str] = set()          # state arrays read or written here
        self.calls: set[str] = set()         # generated functions called here

    # -- output ------------------------------------------------------------------

    def build(self) -> ast.FunctionDef:
        node = self.node
        a = node.args
        if a.vararg or a.kwarg or a.kwonlyargs or a.posonlyargs:
            raise _err(self.fn, node, "*args, **kwargs or keyword-only parameters")
        if node.decorator_list:
            raise _err(self.fn, node, "a decorator")
        params = [STATE]
        for arg, kind in zip(a.args, self.s.kinds):
            self.locals[arg.arg] = kind
            if not isinstance(kind, ListOf):
                params.append(arg.arg)
        defaults: list[ast.expr] = []
        for d in a.defaults:
            if not isinstance(d, ast.Constant):
                raise _err(self.fn, d, "a default that is not a literal")
            defaults.append(d)
        # every local assigned anywhere is a local (Python's rule)
        for sub in ast.walk(node):
            if isinstance(sub, ast.Name) and isinstance(sub.ctx, ast.Store):
                self.locals.setdefault(sub.id, None)
        body = [self.stmt(st) for st in node.body]
        args = ast.arguments(posonlyargs=[], args=[ast.arg(p) for p in params],
                             kwonlyargs=[], kw_defaults=[], defaults=defaults)
        out = ast.FunctionDef(name=self.s.name, args=args,
                              body=[b for b in body if b is not None] or [ast.Pass()],
                              decorator_list=[], returns=None)
        return out

    def origin(self) -> str:
        # the module's own name, not its package: the generated text (and so
        # the cache key) is the same wherever a behaviour's folder lies and
        # whatever it is called, so an unedited copy loads the compiled code
        return f"# {self.fn.__module__.rsplit('.', 1)[-1]}.{self.fn.__qualname__}"

    # -- statements ----------------------------------------------------------------

    def stmt(self, st: ast.stmt) -> ast.stmt | None:
        if isinstance(st, ast.Expr):
            if isinstance(st.value, ast.Constant):
                return None                       # a docstring
            return ast.Expr(self.scalar(st.value))
        if isinstance(st, ast.Assign):
            if len(st.targets) != 1:
                raise _err(self.fn, st, "a chained assignment")
            return self.assign(st.targets[0], st.value, st)
        if isinstance(st, ast.AugAssign):
            target = self.store(st.target, SCALAR, st)
            value = self.scalar(st.value)
            if self.cell(target):                # `t = fits(t op value)`: checked
                now = ast.BinOp(self.scalar(st.target), st.op, value)
                return ast.Assign(targets=[target], value=self.checked(target, now, None))
            return ast.AugAssign(target=target, op=st.op, value=value)
        if isinstance(st, ast.If):
            return ast.If(test=self.scalar(st.test), body=self.block(st.body),
                          orelse=self.block(st.orelse))
        if isinstance(st, ast.While):
            if st.orelse:
                raise _err(self.fn, st, "while ... else")
            return ast.While(test=self.scalar(st.test), body=self.block(st.body), orelse=[])
        if isinstance(st, ast.For):
            if st.orelse:
                raise _err(self.fn, st, "for ... else")
            it, kind = self.expr(st.iter)
            if kind != SCALAR:
                raise _err(self.fn, st, "a for loop over objects")
            target = self.store(st.target, SCALAR, st)
            return ast.For(target=target, iter=it, body=self.block(st.body), orelse=[])
        if isinstance(st, ast.Return):
            if st.value is None:
                return st
            return ast.Return(self.scalar(st.value, "returning an object"))
        if isinstance(st, (ast.Pass, ast.Break, ast.Continue)):
            return st
        raise _err(self.fn, st, f"a {type(st).__name__} statement")

    def block(self, stmts: list[ast.stmt]) -> list[ast.stmt]:
        out = [b for b in (self.stmt(s) for s in stmts) if b is not None]
        return out or ([ast.Pass()] if stmts else [])

    def assign(self, target: ast.expr, value: ast.expr, st: ast.stmt) -> ast.stmt:
        if isinstance(target, ast.Tuple):
            if not isinstance(value, ast.Tuple) or len(value.elts) != len(target.elts):
                raise _err(self.fn, st, "unpacking anything but a tuple display")
            vals = [self.scalar(v) for v in value.elts]
            tgts: list[ast.expr] = [self.store(t, SCALAR, st) for t in target.elts]
            vals = [self.checked(t, v, src) for t, v, src in zip(tgts, vals, value.elts)]
            return ast.Assign(targets=[ast.Tuple(tgts, ast.Store())],
                              value=ast.Tuple(vals, ast.Load()))
        v, kind = self.expr(value)
        if isinstance(kind, Row):             # a local view of the row
            v, kind = ast.Subscript(self._row_arr(kind), kind.index, ast.Load()), SCALAR
        if isinstance(kind, ListOf):
            raise _err(self.fn, st, "a list of objects stored in a variable")
        t = self.store(target, kind, st)
        return ast.Assign(targets=[t], value=self.checked(t, v, value))

    def store(self, target: ast.expr, kind: Any, st: ast.AST
              ) -> ast.Name | ast.Attribute | ast.Subscript:
        if isinstance(target, ast.Name):
            old = self.locals.get(target.id)
            if target.id in self.locals and old is not None and old != kind:
                raise _err(self.fn, st, f"variable {target.id!r} holding values of two types")
            self.locals[target.id] = kind
            return ast.Name(target.id, ast.Store())
        if isinstance(target, ast.Attribute):
            base, bkind = self.expr(target.value)
            if not isinstance(bkind, Inst):
                raise _err(self.fn, st, f"assigning the attribute {target.attr!r} of a "
                                        "non-object")
            cl = self.p.layout.classes[bkind.cls]
            f = cl.fields.get(target.attr)
            if f is None:
                raise _err(self.fn, st, f"a new attribute {bkind.cls.__name__}.{target.attr}")
            if f[0] == "inst":
                if kind != Inst(f[1]):
                    raise _err(self.fn, st, f"{bkind.cls.__name__}.{target.attr} assigned "
                                            "something other than its object")
            elif f[0] in ("row", "array"):
                raise _err(self.fn, st, f"rebinding the list or array "
                                        f"{bkind.cls.__name__}.{target.attr}")
            elif kind != SCALAR:
                raise _err(self.fn, st, f"an object stored in the int field "
                                        f"{bkind.cls.__name__}.{target.attr}")
            return self.column(cl, target.attr, base, ast.Store())
        if isinstance(target, ast.Subscript):
            base, bkind = self.expr(target.value)
            idx = self.scalar(target.slice)
            if isinstance(bkind, Row):
                return ast.Subscript(self._row_arr(bkind),
                                     ast.Tuple([bkind.index, idx], ast.Load()), ast.Store())
            if bkind != SCALAR:
                raise _err(self.fn, st, "assigning an item of a list of objects")
            return ast.Subscript(base, idx, ast.Store())
        raise _err(self.fn, st, f"assigning to a {type(target).__name__}")

    # -- expressions -------------------------------------------------------------------

    def state(self, name: str) -> ast.expr:
        """A state array (or count): a parameter of the function once rendered."""
        self.uses.add(name)
        return ast.Attribute(ast.Name(STATE, ast.Load()), name, ast.Load())

    def arr(self, cl: ClassLayout, attr: str) -> ast.expr:
        return self.state(array_name(cl, attr))

    def column(self, cl: ClassLayout, attr: str, index: ast.expr, ctx: ast.expr_context
               ) -> ast.Subscript:
        """An int, bool or object field of instance `index`: its cell of the table."""
        return ast.Subscript(self.state(ints_name(cl)),
                             ast.Tuple([index, ast.Constant(cl.columns[attr])], ast.Load()),
                             ctx)

    def _row_arr(self, row: Row) -> ast.expr:
        return self.state(row.arr)

    def proven(self, e: ast.expr) -> bool:
        """Whether every value of source expression `e` fits TABLE: an int
        literal or module constant that does, a comparison or `not`, a
        remainder by a positive literal, a conditional or `and`/`or` of such, or an int, bool or object field
        of an object (a table cell: every store into one fits, proved or
        checked)."""
        if isinstance(e, ast.Constant):
            return in_table(e.value)
        if isinstance(e, ast.Name):
            return e.id not in self.locals and e.id in self.glob and in_table(self.glob[e.id])
        if isinstance(e, ast.Attribute):
            _, kind = self.expr(e.value)
            if isinstance(kind, Inst):
                f = self.p.layout.classes[kind.cls].fields.get(e.attr)
                return f is not None and f[0] in ("int", "bool", "inst")
            return isinstance(kind, tuple) and kind[0] == "module" and \
                in_table(getattr(kind[1], e.attr, None))
        if isinstance(e, ast.Compare) or (isinstance(e, ast.UnaryOp) and isinstance(e.op, ast.Not)):
            return True
        if isinstance(e, ast.BinOp) and isinstance(e.op, ast.Mod):    # 0..m-1: Python's sign rule
            m = e.right.value if isinstance(e.right, ast.Constant) else None
            return isinstance(m, int) and 0 < m and in_table(m - 1)
        if isinstance(e, ast.IfExp):
            return self.proven(e.body) and self.proven(e.orelse)
        if isinstance(e, ast.BoolOp):
            return all(self.proven(v) for v in e.values)
        return False

    def cell(self, target: ast.expr) -> bool:
        """Whether a generated store target is a cell of a class's table."""
        return isinstance(target, ast.Subscript) and isinstance(target.value, ast.Attribute) \
            and any(target.value.attr == ints_name(c) for c in self.p.layout.classes.values())

    def checked(self, target: ast.expr, value: ast.expr, source: ast.expr | None) -> ast.expr:
        """`value` to store into `target`: itself, or borrow.fits(value) (a
        typed error for a value outside TABLE) when the target is a table
        cell and its `source` is not proven to fit (None: not one
        expression)."""
        if not self.cell(target):
            return value
        if source is not None and self.proven(source):
            return value
        return ast.Call(ast.Name("fits", ast.Load()), [value], [])

    def scalar(self, e: ast.expr, what: str = "an object used as a value") -> ast.expr:
        v, kind = self.expr(e)
        if isinstance(kind, Row):
            return ast.Subscript(self._row_arr(kind), kind.index, ast.Load())
        if kind != SCALAR:
            raise _err(self.fn, e, what)
        return v

    def expr(self, e: ast.expr) -> tuple[ast.expr, Any]:
        if isinstance(e, ast.Constant):
            return e, SCALAR
        if isinstance(e, ast.Name):
            return self.name(e)
        if isinstance(e, ast.Attribute):
            return self.attribute(e)
        if isinstance(e, ast.Subscript):
            base, kind = self.expr(e.value)
            if isinstance(kind, Row):
                return ast.Subscript(self._row_arr(kind),
                                     ast.Tuple([kind.index, self.scalar(e.slice)], ast.Load()),
                                     ast.Load()), SCALAR
            if isinstance(kind, ListOf):
                return self.scalar(e.slice), Inst(kind.cls)
            if kind != SCALAR:
                raise _err(self.fn, e, "indexing an object")
            return ast.Subscript(base, self.scalar(e.slice), ast.Load()), SCALAR
        if isinstance(e, ast.Call):
            return self.call(e)
        if isinstance(e, ast.BinOp):
            return ast.BinOp(self.scalar(e.left), e.op, self.scalar(e.right)), SCALAR
        if isinstance(e, ast.UnaryOp):
            return ast.UnaryOp(e.op, self.scalar(e.operand)), SCALAR
        if isinstance(e, ast.BoolOp):
            return ast.BoolOp(e.op, [self.scalar(v) for v in e.values]), SCALAR
        if isinstance(e, ast.Compare):
            if any(isinstance(o, (ast.Is, ast.IsNot, ast.In, ast.NotIn)) for o in e.ops):
                raise _err(self.fn, e, "`is` / `in`")
            return ast.Compare(self.scalar(e.left), e.ops,
                               [self.scalar(c) for c in e.comparators]), SCALAR
        if isinstance(e, ast.IfExp):
            return ast.IfExp(self.scalar(e.test), self.scalar(e.body),
                             self.scalar(e.orelse)), SCALAR
        if isinstance(e, ast.Tuple) and isinstance(e.ctx, ast.Load):
            return ast.Tuple([self.scalar(v) for v in e.elts], ast.Load()), SCALAR
        if isinstance(e, ast.Slice):
            parts = [None if p is None else self.scalar(p) for p in (e.lower, e.upper, e.step)]
            return ast.Slice(*parts), SCALAR
        raise _err(self.fn, e, f"a {type(e).__name__} expression")

    def name(self, e: ast.Name) -> tuple[ast.expr, Any]:
        if e.id in self.locals:
            kind = self.locals[e.id]
            if kind is None:
                kind = SCALAR
            return ast.Name(e.id, ast.Load()), kind
        if e.id in self.glob:
            value = self.glob[e.id]
            self.p.lookups[("g", self.glob.get("__name__", ""), e.id)] = describe(value)
            return self.resolved(value, self.fn.__module__, e.id, e)
        if e.id in BUILTINS:
            return ast.Name(e.id, ast.Load()), SCALAR
        raise _err(self.fn, e, f"the name {e.id!r}")

    def resolved(self, value: Any, module: str, name: str, e: ast.AST) -> tuple[ast.expr, Any]:
        if isinstance(value, ModuleType):
            return ast.Name(name, ast.Load()), ("module", value)
        if isinstance(value, CONSTANT_TYPES):
            return ast.Constant(value), SCALAR
        if isinstance(value, FunctionType):
            return ast.Name(name, ast.Load()), ("function", value)
        if isinstance(value, type):
            return ast.Name(name, ast.Load()), ("class", value)
        if isinstance(value, tuple):
            return ast.Name(self.p.global_name(module, name, value), ast.Load()), SCALAR
        raise _err(self.fn, e, f"the global {name!r} (a {type(value).__name__})")

    def attribute(self, e: ast.Attribute) -> tuple[ast.expr, Any]:
        base, kind = self.expr(e.value)
        if isinstance(kind, tuple) and kind[0] == "module":
            mod = kind[1]
            if not hasattr(mod, e.attr):
                raise _err(self.fn, e, f"{mod.__name__}.{e.attr} (no such name)")
            value = getattr(mod, e.attr)
            self.p.lookups[("g", mod.__name__, e.attr)] = describe(value)
            return self.resolved(value, mod.__name__, e.attr, e)
        if isinstance(kind, Inst):
            cl = self.p.layout.classes.get(kind.cls)
            f = cl.fields.get(e.attr) if cl is not None else None
            if cl is None or f is None:
                raise _err(self.fn, e, f"the attribute {kind.cls.__name__}.{e.attr} (not a "
                                       "field of the live instances)")
            if f[0] == "row":
                return ast.Name("_", ast.Load()), Row(array_name(cl, e.attr), base)
            if f[0] == "array":
                if e.attr in cl.views:
                    j, k = cl.views[e.attr]
                    return ast.Name("_", ast.Load()), Row(base_name(cl, j), ast.Constant(k))
                return self.arr(cl, e.attr), SCALAR
            cell = self.column(cl, e.attr, base, ast.Load())
            return cell, (Inst(f[1]) if f[0] == "inst" else SCALAR)
        if isinstance(kind, Row):
            view = ast.Subscript(self._row_arr(kind), kind.index, ast.Load())
            return ast.Attribute(view, e.attr, ast.Load()), SCALAR
        if kind == SCALAR:
            return ast.Attribute(base, e.attr, ast.Load()), SCALAR
        raise _err(self.fn, e, f"the attribute {e.attr!r} of a {kind}")

    def call(self, e: ast.Call) -> tuple[ast.expr, Any]:
        if any(isinstance(a, ast.Starred) for a in e.args) or any(k.arg is None
                                                                  for k in e.keywords):
            raise _err(self.fn, e, "a call with * or ** arguments")
        f = e.func
        # a method of an object
        if isinstance(f, ast.Attribute):
            base, kind = self.expr(f.value)
            if isinstance(kind, Inst):
                meth = inspect.getattr_static(kind.cls, f.attr, None)
                self.p.lookups[("m", kind.cls.__module__, kind.cls.__qualname__, f.attr)] = \
                    describe(meth)
                if not isinstance(meth, FunctionType):
                    raise _err(self.fn, e, f"{kind.cls.__name__}.{f.attr} (not a plain method)")
                return self.invoke(meth, kind.cls, [(base, kind)], e), SCALAR
            if isinstance(kind, tuple) and kind[0] == "module":
                v, k2 = self.attribute(f)
                return self.call_resolved(v, k2, e)
            if kind == SCALAR:
                return ast.Call(ast.Attribute(base, f.attr, ast.Load()),
                                [self.scalar(a) for a in e.args],
                                [ast.keyword(k.arg, self.scalar(k.value)) for k in e.keywords]
                                ), SCALAR
            raise _err(self.fn, e, f"calling {f.attr!r} of a {kind}")
        if isinstance(f, ast.Name):
            if f.id == "len" and f.id not in self.locals and f.id not in self.glob \
                    and len(e.args) == 1:
                v, kind = self.expr(e.args[0])
                if isinstance(kind, ListOf):
                    cl = self.p.layout.classes[kind.cls]
                    return self.state(count_name(cl)), SCALAR
                if isinstance(kind, Row):
                    cl_len = ast.Attribute(self._row_arr(kind), "shape", ast.Load())
                    return ast.Subscript(cl_len, ast.Constant(1), ast.Load()), SCALAR
            v, kind = self.name(f)
            return self.call_resolved(v, kind, e)
        raise _err(self.fn, e, "calling a computed function")

    def call_resolved(self, v: ast.expr, kind: Any, e: ast.Call) -> tuple[ast.expr, Any]:
        if isinstance(kind, tuple) and kind[0] == "function":
            name = INTRINSICS.get(f"{kind[1].__module__}.{kind[1].__qualname__}")
            if name is not None:
                return self.intrinsic(name, e), SCALAR
            return self.invoke(kind[1], None, [], e), SCALAR
        if isinstance(kind, tuple) and kind[0] == "class":
            raise _err(self.fn, e, f"constructing a {kind[1].__name__} (an allocation)")
        if kind == SCALAR and isinstance(v, ast.Name) and v.id in BUILTINS:
            return ast.Call(v, [self.scalar(a) for a in e.args],
                            [ast.keyword(k.arg, self.scalar(k.value)) for k in e.keywords]
                            ), SCALAR
        raise _err(self.fn, e, "calling a value that is not a function")

    def intrinsic(self, name: str, e: ast.Call) -> ast.expr:
        if name == "prefetch_held" or (e.args and isinstance(self.expr(e.args[0])[1], Inst)):
            return self.fetch_rows(name, e)
        args = []
        for a in e.args:
            v, kind = self.expr(a)
            if isinstance(kind, Row):
                v = ast.Subscript(self._row_arr(kind), kind.index, ast.Load())
            elif isinstance(kind, ListOf):
                v = self.state(ints_name(self.p.layout.classes[kind.cls]))
            elif kind != SCALAR:
                raise _err(self.fn, e, f"passing a {kind} to {name}")
            args.append(v)
        return ast.Call(ast.Name(name, ast.Load()), args, [])

    def fetch_rows(self, name: str, e: ast.Call) -> ast.expr:
        """`prefetch(obj, k)`: element k of every row of a per-robot table
        the object's fields view (the HAL's rows of robot k); `prefetch_held(
        objs, k)`: the table row (and list rows) of each object objs[k]'s
        fields hold. A tuple of prefetches, or None when there is nothing."""
        if len(e.args) != 2 or e.keywords:
            raise _err(self.fn, e, f"{name} without exactly (objects, index)")
        _, kind = self.expr(e.args[0])
        k = self.scalar(e.args[1])
        fetch = ast.Name("prefetch", ast.Load())
        calls: list[ast.expr] = []
        if name == "prefetch" and isinstance(kind, Inst):
            cl = self.p.layout.classes[kind.cls]
            for j, row in cl.views.values():
                view = ast.Subscript(self.state(base_name(cl, j)), ast.Constant(row), ast.Load())
                calls.append(ast.Call(fetch, [view, k], []))
        elif name == "prefetch_held" and isinstance(kind, ListOf):
            cl = self.p.layout.classes[kind.cls]
            for attr, f in cl.fields.items():
                if f[0] != "inst":
                    continue
                sub = self.p.layout.classes[f[1]]
                at = self.column(cl, attr, k, ast.Load())
                calls.append(ast.Call(fetch, [self.state(ints_name(sub)), at], []))
                calls += [ast.Call(fetch, [self.arr(sub, a), at], [])
                          for a, g in sub.fields.items() if g[0] == "row"]
        else:
            raise _err(self.fn, e, f"{name} of a {kind}")
        return ast.Tuple(calls, ast.Load()) if calls else ast.Constant(None)

    def invoke(self, fn: FunctionType, owner: type | None, bound: list, e: ast.Call) -> ast.expr:
        """A call of a transformed function: objects pass as their indices."""
        sig = inspect.signature(fn)
        names = list(sig.parameters)
        given: dict[str, tuple[ast.expr, Any]] = {}
        for name, pair in zip(names, bound):
            given[name] = pair
        rest = names[len(bound):]
        if len(e.args) > len(rest):
            raise _err(self.fn, e, f"too many arguments to {fn.__qualname__}")
        for name, a in zip(rest, e.args):
            given[name] = self.expr(a)
        for k in e.keywords:
            if k.arg not in names or k.arg in given:
                raise _err(self.fn, e, f"the keyword {k.arg!r} of {fn.__qualname__}")
            given[k.arg] = self.expr(k.value)
        args: list[ast.expr] = [ast.Name(STATE, ast.Load())]
        kinds = []
        for name in names:
            if name in given:
                v, kind = given[name]
                if isinstance(kind, Row):
                    v, kind = ast.Subscript(self._row_arr(kind), kind.index, ast.Load()), SCALAR
                if isinstance(kind, tuple):
                    raise _err(self.fn, e, f"passing a {kind[0]} to {fn.__qualname__}")
            else:
                d = sig.parameters[name].default
                if d is inspect.Parameter.empty:
                    raise _err(self.fn, e, f"a missing argument {name!r} of {fn.__qualname__}")
                if not isinstance(d, CONSTANT_TYPES):
                    raise _err(self.fn, e, f"the default of {name!r} of {fn.__qualname__}")
                v, kind = ast.Constant(d), SCALAR
            kinds.append(kind)
            if not isinstance(kind, ListOf):
                args.append(v)
        target = self.p.spec(fn, owner, tuple(kinds))
        self.calls.add(target)
        return ast.Call(ast.Name(target, ast.Load()), args, [])


def generate(layout: Layout, entries: dict[str, tuple[FunctionType, tuple]]
             ) -> tuple[str, dict]:
    """The generated module's source and, per entry name, its function's name."""
    source, names, _ = generate_with_inputs(layout, entries)
    return source, names


def generate_with_inputs(layout: Layout, entries: dict[str, tuple[FunctionType, tuple]]
                         ) -> tuple[str, dict, "Inputs | None"]:
    """generate(), and the inputs the text was made from (None when one of
    them cannot be checked again in another process: then it is not cached)."""
    for cl in layout.classes.values():
        cl.finish()
    p = Program(layout)
    names = {key: p.entry(fn, kinds) for key, (fn, kinds) in entries.items()}
    rendered = p.render()
    params = p.params()
    lines = ['"""Generated by sim_backend/batch/transform.py from the firmware source; '
             'do not edit."""',
             "from numba import njit",
             f"from sim_backend.batch.borrow import NoAlias, borrow, clear, fits, prefetch  "
             f"# {CODEGEN}; borrow.py {_borrow_hash()[:16]}",
             ""]
    for cl in layout.classes.values():
        cols = ", ".join(f"{a}={k}" for a, k in cl.columns.items())
        lines.append(f"# {ints_name(cl)}[i, k] ({np.dtype(TABLE).name}) holds "
                     f"{cl.cls.__qualname__}.{{{cols}}}")
        for attr, (j, k) in cl.views.items():
            lines.append(f"# {cl.cls.__qualname__}.{attr} is {base_name(cl, j)}[{k}]")
    lines.append("")
    for key, name in names.items():
        lines.append(f"E_{name}__STATE = {tuple(params[name])!r}   # its leading arguments")
    for g, lit in sorted(p.globals.items()):
        lines.append(f"{g} = {lit}")
    lines.append("")
    # TOUCHSWARM_SOA_INLINE=0: about half the cold compile for a tenth of the speed,
    # for a behaviour being edited (each edit is a new module; docs/performance.md)
    inline = p.robot_path(entries) if os.environ.get("TOUCHSWARM_SOA_INLINE", "1") != "0" \
        else set()
    entries_called: list[str] = []      # what Python calls: every array borrowed (borrow.py)
    for (origin, src), name in zip(rendered, p.done):
        deco = "@njit(cache=True, forceinline=True)" if name in inline else "@njit(cache=True)"
        lines += ["", origin, deco, src, ""]
        if name in names.values():
            args = [a.arg for a in ast.parse(src).body[0].args.args]  # type: ignore[attr-defined]
            entries_called += ["", "@njit(cache=True, pipeline_class=NoAlias)",
                               f"def E_{name}({', '.join(args)}):",
                               f"    return {name}({', '.join(f'borrow({a})' for a in args)})",
                               ""]
    lines += entries_called
    return ("\n".join(lines) + "\n", {k: "E_" + v for k, v in names.items()},
            Inputs.of(p))


# -- what a generated text was made from: the key and check of its cache -------------------
#
# sim_backend/batch/soa.py keeps each generated text with the inputs it was
# read from, so a warm engine skips the transform (about 0.2 s of CPU, most of
# an engine's build). Its key is `shape(layout, entries)`: this file's own
# text, the Python version, the inlining switch, and the classes, fields and
# entry points (what the live instances say) with the files they are defined
# in (so each source tree has its own). Under one key, a text is used
# again only while `Inputs.hold()`: every source file a transformed function
# was read from (and every file defining a class of the layout) has the same
# content, and every global name and method the transform resolved still
# resolves to the same thing (a module constant, a function, a class). An
# edit anywhere the transform read is a new text.

_MISSING = object()


def describe(value: Any) -> str:
    """What a resolved name holds, as the cache compares it across processes."""
    if value is _MISSING:
        return "missing"
    if isinstance(value, ModuleType):
        return f"module {value.__name__}"
    if isinstance(value, FunctionType):
        c = value.__code__
        return f"function {value.__module__}.{value.__qualname__} {c.co_filename}:" \
               f"{c.co_firstlineno}"
    if isinstance(value, type):
        return f"class {value.__module__}.{value.__qualname__}"
    if isinstance(value, CONSTANT_TYPES) or (isinstance(value, tuple) and all(
            isinstance(v, CONSTANT_TYPES) for v in value)):
        return f"{type(value).__name__} {value!r}"
    return f"object {type(value).__qualname__} {id(value)}"     # never equal in another process


def _file_hash(path: str) -> str | None:
    try:
        with open(path, "rb") as f:
            return hashlib.sha256(f.read()).hexdigest()
    except OSError:
        return None


_SELF: list[str] = []
_BORROW: list[str] = []


def _borrow_hash() -> str:
    """borrow.py's content hash, part of every generated text: numba compiles
    its intrinsics and checks into the text's functions, and a numba cache
    is only checked against its own file, so a change there must be a new
    text (and cache folder) too."""
    if not _BORROW:
        _BORROW.append(_file_hash(os.path.join(os.path.dirname(__file__), "borrow.py")) or "")
    return _BORROW[0]


def _kind_key(kind: Any) -> str:
    if isinstance(kind, tuple) and kind[:1] == ("row",):
        return "row"                 # a list's length is the arrays', not the text's
    if isinstance(kind, (ListOf, Inst)):
        return f"{type(kind).__name__} {kind.cls.__module__}.{kind.cls.__qualname__}"
    if isinstance(kind, tuple):
        return repr(tuple(f"{k.__module__}.{k.__qualname__}" if isinstance(k, type) else k
                          for k in kind))
    return repr(kind)


def _where(cls: type) -> str:
    try:
        return inspect.getfile(cls)
    except (TypeError, OSError):
        return "?"


def shape(layout: Layout, entries: dict[str, tuple[FunctionType, tuple]]) -> str:
    """The cache key of the text `generate(layout, entries)` makes, given that
    its `Inputs` hold: everything it depends on that is not a source file.
    The files the classes and entry points are defined in are part of it: two
    source trees sharing one cache (two checkouts, an install and a clone)
    each keep their own text, where one key would have each tree's build
    overwrite the other's and transform again."""
    if not _SELF:
        _SELF.append(_file_hash(__file__) or "")
    parts = [_SELF[0], _borrow_hash(), CODEGEN, repr(sys.version_info[:2]),
             os.environ.get("TOUCHSWARM_SOA_INLINE", "1")]
    for cl in layout.classes.values():
        cl.finish()
        parts.append(f"{cl.cls.__module__}.{cl.cls.__qualname__} in {_where(cl.cls)} as "
                     f"{cl.name}: " + ", ".join(
                         f"{a}={_kind_key(k)}" for a, k in cl.fields.items())
                     + f" views {cl.views}")
    for key, (fn, kinds) in entries.items():
        parts.append(f"{key}: {fn.__module__}.{fn.__qualname__} in {fn.__code__.co_filename}"
                     f"({', '.join(_kind_key(k) for k in kinds)})")
    return hashlib.sha256("\n".join(parts).encode()).hexdigest()[:24]


@dataclass
class Inputs:
    """The files (path -> sha256 of its content) and resolved names (key ->
    `describe` of its value) a generated text was read from."""
    files: dict[str, str]
    lookups: dict[tuple[str, ...], str]

    @classmethod
    def of(cls, p: Program) -> "Inputs | None":
        files = set(p.files)
        for cl in p.layout.classes.values():
            for c in cl.cls.__mro__:
                if c.__module__ != "builtins":
                    try:
                        files.add(inspect.getfile(c))
                    except (TypeError, OSError):
                        return None
        hashes = {}
        for f in sorted(files):
            h = _file_hash(f)
            if h is None:
                return None                      # not a file (exec'd, zipped): not cached
            hashes[f] = h
        if any("<locals>" in k[2] for k in p.lookups if k[0] == "m"):
            return None
        return cls(hashes, dict(p.lookups))

    def hold(self) -> bool:
        """Whether every input is still what the text was made from."""
        for key, was in self.lookups.items():
            mod = sys.modules.get(key[1])
            if mod is None:
                return False
            if key[0] == "g":
                now = describe(getattr(mod, key[2], _MISSING))
            else:
                owner: Any = mod
                for part in key[2].split("."):
                    owner = getattr(owner, part, _MISSING)
                if not isinstance(owner, type):
                    return False
                now = describe(inspect.getattr_static(owner, key[3], None))
            if now != was:
                return False
        return all(_file_hash(f) == h for f, h in self.files.items())

    def to_json(self) -> dict:
        return {"files": self.files, "lookups": [list(k) + [v] for k, v in self.lookups.items()]}

    @classmethod
    def from_json(cls, d: dict) -> "Inputs":
        return cls(dict(d["files"]), {tuple(x[:-1]): x[-1] for x in d["lookups"]})


def state_arrays(layout: Layout) -> dict[str, Any]:
    """The arrays of every class, filled from the live instances (the arrays
    that array fields view are shared, not copied)."""
    out: dict[str, Any] = {}
    for cl in layout.classes.values():
        n = len(cl.instances)
        out[count_name(cl)] = n
        ints = np.zeros((n, max(1, len(cl.columns))), dtype=TABLE)
        out[ints_name(cl)] = ints
        for j, b in enumerate(cl.bases):
            out[base_name(cl, j)] = b
        values = layout.values(cl)
        for attr, f in cl.fields.items():
            vals = values[attr]
            if attr in cl.columns:
                if f[0] == "inst":
                    vals = [layout.index[id(v)][1] for v in vals]
                if vals and not (in_table(min(vals)) and in_table(max(vals))):
                    bad = next(v for v in vals if not in_table(v))
                    raise CompileError(f"{cl.cls.__name__}.{attr} = {bad}: outside the "
                                       f"{np.dtype(TABLE).name} the batch engine keeps an int "
                                       "field in (a firmware int lives in 31 bits)")
                ints[:, cl.columns[attr]] = vals
            elif f[0] == "row":
                a = np.zeros((n, f[1]), dtype=np.int64)
                if f[1]:
                    a[:] = vals
                out[array_name(cl, attr)] = a
            elif attr not in cl.views:
                out[array_name(cl, attr)] = vals[0]
    _apart(layout, out)
    return out


def _apart(layout: Layout, arrays: dict[str, Any]) -> None:
    """Raise unless the entries' arrays are apart, as their `noalias`
    arguments promise LLVM (borrow.NoAlias): no two share memory, but one
    base array that several classes view, each through rows of its own (the
    batch's robot table: the kernel's Robots rows and the body's own)."""
    owner: dict[tuple[int, int], str] = {}
    for cl in layout.classes.values():
        for attr, (j, k) in cl.views.items():
            key = (id(cl.bases[j]), k)
            if owner.setdefault(key, cl.name) != cl.name:
                raise CompileError(f"{cl.name}.{attr}: row {k} of an array {owner[key]} "
                                   "views too (the compiled step needs its arrays apart)")
    distinct = list({id(a): (name, a) for name, a in arrays.items()
                     if isinstance(a, np.ndarray)}.values())
    for x, (name, a) in enumerate(distinct):
        for other, b in distinct[x + 1:]:
            if np.may_share_memory(a, b):
                raise CompileError(f"{name} and {other} share memory (the compiled step "
                                   "needs its arrays apart)")


def unpack(layout: Layout, arrays: dict[str, Any], objs: Sequence[Any]) -> None:
    """Write instances' fields (and their objects') back from the arrays,
    instance by instance, each class's table rows converted in one call and
    its fields sorted by kind once (a 10,000-robot run's end cost about as
    much as 40 of its ticks)."""
    groups: dict[type, list[Any]] = {}
    for o in objs:
        groups.setdefault(type(o), []).append(o)
    for cls, group in groups.items():
        cl = layout.classes[cls]
        js = [layout.index[id(o)][1] for o in group]
        ints = [(a, cl.columns[a]) for a, f in cl.fields.items() if f[0] == "int"]
        flags = [(a, cl.columns[a]) for a, f in cl.fields.items() if f[0] == "bool"]
        lists = [(a, arrays[array_name(cl, a)]) for a, f in cl.fields.items() if f[0] == "row"]
        for o, j, row in zip(group, js, arrays[ints_name(cl)][js].tolist()):
            for a, c in ints:
                setattr(o, a, row[c])
            for a, c in flags:
                setattr(o, a, bool(row[c]))
            for a, arr in lists:
                getattr(o, a)[:] = arr[j].tolist()
        for a, f in cl.fields.items():
            if f[0] == "inst":
                unpack(layout, arrays, [getattr(o, a) for o in group])
