"""The arena the user draws: `[[objects]]` and `[[obstacles]]` tables of a
scenario, parsed into objects.Piece and checked (docs/scenarios.md).

Every error is one line naming the table, its index (0-based, in file order)
and the key: `objects[1].at: ...`.
"""

from __future__ import annotations

from typing import Any

from firmware_logic.behaviours.thesis.coordinator import way_home
from sim_backend import objects
from sim_backend.errors import ScenarioError
from sim_backend.objects import Piece

OBJECT_KEYS = ("name", "art", "cells", "shape", "at", "weight", "density", "target")
OBSTACLE_KEYS = ("name", "art", "cells", "shape", "at")
LIBRARY_KEYS = ("name", "art", "cells", "shape")
OBJECT_ONLY = {"weight": 0.0, "density": None, "target": False}
FLAT_OBJECT_KEYS = ("object", "objectX", "objectY", "objectWeight")
WEIGHT = (0.01, 10000.0)
DENSITY = (0.001, 1000.0)
COORD = (-400, 400)
MAX_CELLS = 4096
DEFAULT_WEIGHT = 5.0      # Scenario.objectWeight's default
FIELD_MODES = ("static", "dynamic")
CROWD_MODES = ("block", "yield")


def _num(where: str, value: Any, lo: float, hi: float) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or value != value \
            or not lo <= value <= hi:
        raise ScenarioError(f"{where}: expected a number in {lo:g}..{hi:g}, got {value!r}")
    return float(value)


def _int_pair(where: str, value: Any) -> tuple[int, int]:
    ok = isinstance(value, (list, tuple)) and len(value) == 2 and all(
        isinstance(v, int) and not isinstance(v, bool) for v in value)
    if not ok:
        raise ScenarioError(f"{where}: expected [x, y], two integers, got {value!r}")
    x, y = value
    if not (COORD[0] <= x <= COORD[1] and COORD[0] <= y <= COORD[1]):
        raise ScenarioError(f"{where}: {value!r} is outside {COORD[0]}..{COORD[1]}")
    return x, y


def _cells(where: str, t: dict) -> tuple[tuple[int, int], ...]:
    given = [k for k in ("art", "cells", "shape") if k in t]
    if len(given) != 1:
        raise ScenarioError(f"{where}: give exactly one of art, cells or shape, got "
                            f"{', '.join(given) or 'none'}")
    key = given[0]
    value = t[key]
    if key == "art":
        if not isinstance(value, str):
            raise ScenarioError(f"{where}.art: expected a string of rows, got {value!r}")
        try:
            cs = objects.art_cells(value)
        except ValueError as err:
            raise ScenarioError(f"{where}.art: {err}") from None
    elif key == "shape":
        if not isinstance(value, str) or value not in objects.SHAPES:
            raise ScenarioError(f"{where}.shape: expected one of "
                                f"{', '.join(sorted(objects.SHAPES))}, got {value!r}")
        cs = objects.offsets(value)
    else:
        if not isinstance(value, (list, tuple)):
            raise ScenarioError(f"{where}.cells: expected a list of [x, y], got {value!r}")
        cs = [_int_pair(f"{where}.cells[{j}]", c) for j, c in enumerate(value)]
        if len(set(cs)) != len(cs):
            dup = next(c for c in cs if cs.count(c) > 1)
            raise ScenarioError(f"{where}.cells: cell {list(dup)} is given twice")
    if not cs:
        raise ScenarioError(f"{where}.{key}: no cells; draw at least one '#'")
    if len(cs) > MAX_CELLS:
        raise ScenarioError(f"{where}.{key}: {len(cs)} cells, at most {MAX_CELLS}")
    return tuple(cs)


def _table(where: str, t: Any, keys: tuple[str, ...]) -> dict:
    if isinstance(t, Piece):
        t = {k: getattr(t, k) for k in ("name", "cells", "at", "weight", "density", "target")
             if k in keys}
    if not isinstance(t, dict):
        raise ScenarioError(f"{where}: expected a table ([[{where.split('[')[0]}]]), got {t!r}")
    if "weight" not in keys:
        # a Piece's dict (Scenario.to_dict) carries an obstacle's unused fields
        t = {k: v for k, v in t.items() if not (k in OBJECT_ONLY and v == OBJECT_ONLY[k])}
    unknown = sorted(set(t) - set(keys))
    if unknown:
        raise ScenarioError(f"{where}: unknown key {unknown[0]!r}; known keys: {', '.join(keys)}")
    return t


def _object(j: int, t: Any) -> tuple[Piece, bool | None]:
    """The piece (its target resolved by the caller, across all objects) and
    the table's target: None when the table does not say."""
    where = f"objects[{j}]"
    t = _table(where, t, OBJECT_KEYS)
    cs = _cells(where, t)
    name = str(t.get("name", f"object{j}"))
    _not_reserved(where, name)
    at = None if t.get("at") is None else _int_pair(f"{where}.at", t["at"])
    target = t.get("target", None)
    if target is not None and not isinstance(target, bool):
        raise ScenarioError(f"{where}.target: expected true or false, got {target!r}")
    density = None
    if t.get("density") is not None:
        density = _num(f"{where}.density", t["density"], *DENSITY)
        weight = round(density * len(cs), 6)
        if t.get("weight") is not None and abs(float(t["weight"]) - weight) > 1e-6:
            raise ScenarioError(f"{where}: give weight or density, not both (density "
                                f"{density:g} x {len(cs)} cells = {weight:g}, weight "
                                f"{t['weight']!r})")
        if not WEIGHT[0] <= weight <= WEIGHT[1]:
            raise ScenarioError(f"{where}.density: {density:g} x {len(cs)} cells = weight "
                                f"{weight:g}, outside {WEIGHT[0]:g}..{WEIGHT[1]:g}")
    elif t.get("weight") is not None:
        weight = _num(f"{where}.weight", t["weight"], *WEIGHT)
    else:
        weight = DEFAULT_WEIGHT
    return Piece(name, cs, at, weight, density), target


def _obstacle(j: int, t: Any) -> Piece:
    where = f"obstacles[{j}]"
    t = _table(where, t, OBSTACLE_KEYS)
    cs = _cells(where, t)
    if t.get("at") is None:
        raise ScenarioError(f"{where}.at: required, the art's lower-left cell [x, y]")
    return Piece(str(t.get("name", f"obstacle{j}")), cs, _int_pair(f"{where}.at", t["at"]))


def _not_reserved(where: str, name: str) -> None:
    if name == objects.UNKNOWN:
        raise ScenarioError(f"{where}.name: {name!r} is reserved (the recogniser's name for a "
                            "shape it does not know); choose another")


def _known(j: int, t: Any) -> Piece:
    """A [[library]] table: a shape the host's recogniser knows by name
    (perception/shapes.py), placed nowhere in the world."""
    where = f"library[{j}]"
    if isinstance(t, dict):     # a Piece's dict (Scenario.to_dict) carries unused fields
        t = {k: v for k, v in t.items()
             if not (k == "at" and v is None) and not (k in OBJECT_ONLY and v == OBJECT_ONLY[k])}
    t = _table(where, t, LIBRARY_KEYS)
    if "name" not in t or not isinstance(t["name"], str) or not t["name"]:
        raise ScenarioError(f"{where}.name: required, the name the host reports the shape by")
    _not_reserved(where, t["name"])
    return Piece(t["name"], _cells(where, t))


def _array(key: str, value: Any) -> list:
    if not isinstance(value, (list, tuple)):
        raise ScenarioError(f"{key}: expected an array of tables ([[{key}]]), got {value!r}")
    return list(value)


def parse(raw: dict[str, Any], values: dict[str, Any]) -> dict[str, Any]:
    """Take `objects`, `obstacles` and `field` out of raw into values (as
    Pieces); with objects, the flat object keys are derived from the target
    (given, they must agree). Returns the keys left for the flat parser."""
    raw = dict(raw)
    if "field" in raw:
        f = raw.pop("field")
        if f not in FIELD_MODES:
            raise ScenarioError(f"field: expected one of {', '.join(FIELD_MODES)}, got {f!r}")
        values["field"] = f
    if "crowd" in raw:
        f = raw.pop("crowd")
        if f not in CROWD_MODES:
            raise ScenarioError(f"crowd: expected one of {', '.join(CROWD_MODES)}, got {f!r}")
        values["crowd"] = f
    if "wrap" in raw:
        f = raw.pop("wrap")
        if not isinstance(f, bool):
            raise ScenarioError(f"wrap: expected true or false, got {f!r}")
        values["wrap"] = f
    if "library" in raw:
        known = tuple(_known(j, t) for j, t in enumerate(_array("library", raw.pop("library"))))
        names = [p.name for p in known]
        for j, n in enumerate(names):
            if names.index(n) != j:
                raise ScenarioError(f"library[{j}].name: {n!r} is taken by "
                                    f"library[{names.index(n)}]")
        values["library"] = known
    if "obstacles" in raw:
        values["obstacles"] = tuple(_obstacle(j, t) for j, t in
                                    enumerate(_array("obstacles", raw.pop("obstacles"))))
    if "objects" not in raw:
        return raw
    given = [_object(j, t) for j, t in enumerate(_array("objects", raw.pop("objects")))]
    if not given:
        return raw
    pieces = [p for p, _ in given]
    names = [p.name for p in pieces]
    for j, p in enumerate(pieces):
        if names.index(p.name) != j:
            raise ScenarioError(f"objects[{j}].name: {p.name!r} is taken by "
                                f"objects[{names.index(p.name)}]")
    marked = [j for j, (_, target) in enumerate(given) if target]
    if len(given) == 1 and given[0][1] is None:
        marked = [0]
    if len(marked) != 1:
        raise ScenarioError(f"objects: exactly one object must have target = true, got "
                            f"{len(marked)} ({', '.join(f'objects[{j}]' for j in marked) or 'none'})")
    for j, p in enumerate(pieces):
        if j != marked[0] and p.at is None:
            raise ScenarioError(f"objects[{j}].at: required for an object that is not the "
                                "target (only the target may be placed as CreateWorld does)")
    pieces = [Piece(p.name, p.cells, p.at, p.weight, p.density, j == marked[0])
              for j, p in enumerate(pieces)]
    t = pieces[marked[0]]
    derived = {"object": t.name, "objectX": None if t.at is None else t.at[0],
               "objectY": None if t.at is None else t.at[1], "objectWeight": t.weight}
    for key in FLAT_OBJECT_KEYS:
        if key in raw and raw[key] != derived[key]:
            raise ScenarioError(f"{key}: set by [[objects]] (the target {t.name!r}); remove "
                                f"the flat key {key} = {raw[key]!r}")
        raw.pop(key, None)
    values.update(derived)
    values["objects"] = tuple(pieces)
    return raw


def anchors(p: Piece) -> list[tuple[int, int]]:
    """Every anchor a piece may get: its `at`, or CreateWorld's `random 10`."""
    if p.at is not None:
        return [p.at]
    return [(x, y) for x in range(10) for y in range(10)]


def label(sc: Any, p: Piece) -> str:
    if p in sc.obstacles:
        return f"obstacles[{sc.obstacles.index(p)}]"
    if sc.objects:
        return f"objects[{sc.objects.index(p)}]"
    return "object"


def check_home(sc: Any) -> None:
    """Home lies inside the arena."""
    w = sc.worldSize
    if abs(sc.homeX) > w - 1 or abs(sc.homeY) > w - 1:
        raise ScenarioError(f"homeX/homeY: ({sc.homeX}, {sc.homeY}) must lie within "
                            f"{-w + 1}..{w - 1} (worldSize={w})")


def check_crowd(sc: Any, occupied: int, among: str | None = None) -> None:
    """A quarter of the patches inside the edge, less the `occupied` ones,
    left free for the robots; `among` names what occupies them."""
    w = sc.worldSize
    free = (2 * w - 1) ** 2 - occupied
    if sc.agents <= free // 4:
        return
    if among is None:
        raise ScenarioError(f"agents: {sc.agents} robots crowd a {2 * w + 1}-patch arena; "
                            f"allowed 1..{free // 4} for worldSize={w}")
    raise ScenarioError(f"agents: {sc.agents} robots crowd a {2 * w + 1}-patch arena "
                        f"with {among}; allowed 1..{max(1, free // 4)}")


def check(sc: Any) -> None:
    """Every object and obstacle fits, nothing overlaps, home is clear, the
    target's weight is reachable by the robots that can surround it, it has
    a way home, and the robots do not crowd the arena."""
    w = sc.worldSize
    pieces = sc.pieces()
    check_home(sc)
    taken: dict[tuple[int, int], str] = {}
    # obstacles may touch the wall; objects keep a free patch all round
    for p, margin in [(o, 0) for o in sc.obstacles] + [(o, 1) for o in pieces]:
        name = label(sc, p)
        lim = w - margin
        for ax, ay in anchors(p):
            cs = p.placed(ax, ay)
            xs = [x for x, _ in cs]
            ys = [y for _, y in cs]
            if min(xs) < -lim or max(xs) > lim or min(ys) < -lim or max(ys) > lim:
                where = f"at {list(p.at)}" if p.at else "at a CreateWorld anchor 0..9"
                raise ScenarioError(
                    f"{name}.at: {p.name!r} {where} spans x {min(xs)}..{max(xs)}, y "
                    f"{min(ys)}..{max(ys)}, outside the arena {-lim}..{lim} "
                    f"(worldSize={w}{', with a free patch around objects' if margin else ''})")
            for c in cs:
                if c == (sc.homeX, sc.homeY):
                    raise ScenarioError(f"{name}.at: {p.name!r} covers home "
                                        f"({sc.homeX}, {sc.homeY})")
                if p.at is not None and c in taken and taken[c] != name:
                    raise ScenarioError(f"{name}.at: {p.name!r} overlaps {taken[c]} at "
                                        f"{list(c)}")
        if p.at is not None:
            for c in p.placed(*p.at):
                taken[c] = name
    if not pieces:                       # object = "none": obstacles only
        check_crowd(sc, len(taken), "these obstacles")
        return
    target = pieces[0]
    tname = label(sc, target)
    taken = {c: name for c, name in taken.items() if name != tname}
    for ax, ay in anchors(target):
        cs = target.placed(ax, ay)
        for c in cs:
            if target.at is None and c in taken:
                raise ScenarioError(f"{tname}.at: {target.name!r} placed as CreateWorld does "
                                    f"(anchor 0..9) may overlap {taken[c]} at {list(c)}; "
                                    "give the target an `at`")
            if (c[0] - sc.homeX) ** 2 + (c[1] - sc.homeY) ** 2 < 16:
                raise ScenarioError(f"{tname}.at: {target.name!r} comes within 4 patches of "
                                    f"home ({sc.homeX}, {sc.homeY}) at {list(c)}; it must stay "
                                    "at least 4 patches away")
    if target.at is not None:
        _check_path(sc, target, tname, taken)
    _check_weight(sc, target, tname, taken)
    check_crowd(sc, len(taken) + len(target.cells), "these objects and obstacles")


def _check_weight(sc: Any, target: Piece, tname: str, taken: dict) -> None:
    w = sc.worldSize
    key = f"{tname}.{'density' if target.density is not None else 'weight'}" \
        if sc.objects else "objectWeight"
    from sim_backend.scenario import holders_within_swarm
    needed = holders_within_swarm(sc, round(target.weight * 100), key)
    if needed is None:
        return          # the behaviour holds no objects by weight
    fewest = None
    for ax, ay in anchors(target):
        cs = set(target.placed(ax, ay))

        outside = _outside(sc, set(taken) | cs) if target.at is not None else None

        def free(x: int, y: int) -> bool:
            if outside is not None:
                return (x, y) in outside        # a hole inside the object is no place to stand
            return -w <= x <= w and -w <= y <= w and (x, y) not in taken and (x, y) not in cs

        n = objects.surround(list(cs), free)
        fewest = n if fewest is None else min(fewest, n)
    if fewest is not None and needed > fewest:
        raise ScenarioError(
            f"{key}: weight {target.weight:g} needs {needed} robots holding, but only "
            f"{fewest} can surround {target.name!r} (reachable segments with a free patch "
            "beside them, thesis 6.1.5); lower the weight")


def _outside(sc: Any, closed: set) -> set:
    """The patches a robot can stand on: free of every piece and joined to
    home or the arena's edge by 8-neighbour steps, as robots move (a hole
    the object or obstacles close all round is not)."""
    w = sc.worldSize
    edge = [(x, y) for x in range(-w, w + 1) for y in (-w, w)] + \
        [(x, y) for y in range(-w, w + 1) for x in (-w, w)] + [(sc.homeX, sc.homeY)]
    todo = [p for p in edge if p not in closed]
    seen = set(todo)
    while todo:
        x, y = todo.pop()
        for a in (-1, 0, 1):
            for b in (-1, 0, 1):
                p = (x + a, y + b)
                if p not in seen and -w <= p[0] <= w and -w <= p[1] <= w and p not in closed:
                    seen.add(p)
                    todo.append(p)
    return seen


def _check_path(sc: Any, target: Piece, tname: str, taken: dict) -> None:
    """The target's own cells have a way home round the obstacles and other
    objects (the carriers beside it are planned for at convergence)."""
    assert target.at is not None         # called for a target placed at a given anchor
    cs = target.placed(*target.at)
    dist = way_home(sc.worldSize, cs, set(taken), cs, sc.homeX, sc.homeY, 16, (0, 0))
    if (0, 0) not in dist:
        raise ScenarioError(f"{tname}.at: {target.name!r} has no way home to "
                            f"({sc.homeX}, {sc.homeY}): obstacles or other objects close "
                            "every path its footprint could take")
