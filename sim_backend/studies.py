"""A behaviour's studies: named sweeps over its own parameters and the
figures drawn from them, declared as data in the behaviour's optional
studies.py (docs/writing-a-behaviour.md, "Studies"; the thesis's in
firmware_logic/behaviours/thesis/studies.py).

    STUDIES = ({"name": "spread", "about": "one line", "seeds": 20,
                "until": "delivered",
                "set": (("maxTicks", 2000),),
                "grids": (("spread", (("quietTicks", (10, 40)),)),),
                "points": (("one", (("agents", 12),)),),
                "figures": ({"name": "spread", "kind": "factor",
                             "x": "quietTicks", "y": "home_tick"},)},)

`touchswarm sweep --study NAME` runs one (the scenario's behaviour's). This
module checks a behaviour's studies (a one-line StudyError naming the
behaviour, the study and the key), turns them into sweep Points and draws
their figures with the generic figure kinds of sim_backend/plots.py
(FIGURES). Nothing here knows any behaviour's parameters: the columns a
figure draws come from the study.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

from sim_backend.engine import UNTIL
from sim_backend.errors import ScenarioError
from sim_backend.sweep import Point

# key -> (types, what it holds); name, about and figures are required, and
# points or grids (or both)
STUDY_KEYS: dict[str, tuple[tuple[type, ...], str]] = {
    "name": ((str,), "the study's name, a word (sweep --study NAME)"),
    "about": ((str,), "one line saying what it shows"),
    "seeds": ((int,), "the count of seeds, 1.. (default 20)"),
    "until": ((str,), "delivered or converged (default delivered)"),
    "set": ((tuple,), "((key, value), ...): every point's overrides"),
    "grids": ((tuple,), "((experiment, ((key, (v1, v2, ...)), ...)), ...)"),
    "points": ((tuple,), "((experiment, ((key, value), ...)), ...)"),
    "figures": ((tuple,), "({'name': ..., 'kind': ..., ...}, ...)"),
}
REQUIRED = ("name", "about", "figures")

# figure kind -> (plots function, required keys, optional keys); every figure
# also has a name (its file: NAME.png) and its kind
FIGURES: dict[str, tuple[str, tuple[str, ...], tuple[str, ...]]] = {
    # y (a tick measure) against the numeric column x, one panel per value
    # of series: mean (95% CI), median, censored runs at maxTicks
    "factor": ("factor_plot", ("x", "y"), ("experiment", "series", "title", "ylabel")),
    # several tick columns y ((column, label), ...) against x, log scale,
    # one panel per value of series, over the runs that got there
    "units": ("units_plot", ("x", "y"), ("experiment", "series", "title", "ylabel")),
    # per value of category (levels) and required holders: the median-IoU
    # run's perceived shape over the true cells, and mean IoU against N
    "shapes": ("shapes_plot", ("levels",), ("experiment", "category", "title")),
    # the same runs' touches (holders' rounded positions) over the true
    # cells, the polygon through them and the cells it encloses, and mean y
    # (an IoU column; default shape_iou) against N
    "touchmap": ("touchmap_plot", ("levels",), ("experiment", "category", "title", "y")),
    # delivery rate and median delivery tick against each fault's rate: each
    # experiment is named after the key it varies (reference: a point drawn
    # as a line; scale: ((key, divisor), ...) for a key that is not a rate)
    "rates": ("rates_plot", (), ("reference", "scale", "title")),
    # boxes of y per experiment, levels ((experiment, label), ...) in order
    "levels": ("levels_plot", ("y", "levels"), ("xlabel", "ylabel", "title")),
}


class StudyError(ScenarioError):
    """A study that cannot be run or drawn (one line)."""


@dataclass(frozen=True)
class Study:
    behaviour: str
    name: str
    about: str
    seeds: int
    until: str
    overrides: tuple[tuple[str, Any], ...]
    points: tuple[Point, ...]
    figures: tuple[dict, ...]

    def figure_names(self) -> list[str]:
        return [f["name"] for f in self.figures]


def _kinds(behaviour: str) -> dict[str, str]:
    """key -> "float" for the world's and the behaviour's float keys (a
    study writes a float as text, as spec.PARAMS does)."""
    from sim_backend import params
    from sim_backend.scenario import RANGES
    out = {k: "float" for k, (kind, _, _) in RANGES.items() if kind is float}
    for p in params.declared(behaviour):
        out[p.name] = p.kind
    return out


def _value(kinds: dict[str, str], key: str, value: Any, where: str) -> Any:
    if isinstance(value, str) and kinds.get(key) == "float":
        try:
            return float(value)
        except ValueError:
            raise StudyError(f"{where}: {key} = {value!r}; expected a number "
                             "(a float as text, e.g. \"0.5\")") from None
    return value


def _pairs(value: Any, where: str, what: str) -> tuple[tuple[str, Any], ...]:
    if not isinstance(value, tuple) or not all(
            isinstance(p, tuple) and len(p) == 2 and isinstance(p[0], str) for p in value):
        raise StudyError(f"{where}: {what} {value!r}; expected ((key, value), ...)")
    return value


def _figure(f: Any, where: str) -> dict:
    if not isinstance(f, dict) or not isinstance(f.get("name"), str) or not f["name"]:
        raise StudyError(f"{where}: figure {f!r}; expected a dict with a name, a kind and "
                         "its columns")
    at = f"{where}: figure {f['name']!r}"
    kind = f.get("kind")
    if kind not in FIGURES:
        raise StudyError(f"{at}: kind {kind!r}; expected one of {', '.join(FIGURES)}")
    _, required, optional = FIGURES[kind]
    for key in f:
        if key not in ("name", "kind", *required, *optional):
            raise StudyError(f"{at}: unknown key {key!r}; a {kind} figure takes "
                             f"{', '.join((*required, *optional))}")
    for key in required:
        if key not in f:
            raise StudyError(f"{at}: no {key!r}; a {kind} figure needs "
                             f"{', '.join(required)}")
    if "/" in f["name"] or f["name"].startswith("."):
        raise StudyError(f"{at}: a figure's name is its file NAME.png; expected a word")
    return dict(f)


def _study(behaviour: str, raw: Any, kinds: dict[str, str]) -> Study:
    where = f"behaviour {behaviour!r}: studies.py"
    if not isinstance(raw, dict) or not isinstance(raw.get("name"), str):
        raise StudyError(f"{where}: study {str(raw)[:60]!r}; expected a dict with a name "
                         "(docs/writing-a-behaviour.md, \"Studies\")")
    where += f" study {raw['name']!r}"
    for key, value in raw.items():
        if key not in STUDY_KEYS:
            raise StudyError(f"{where}: unknown key {key!r}; a study's keys: "
                             f"{', '.join(STUDY_KEYS)}")
        types, what = STUDY_KEYS[key]
        if not isinstance(value, types) or isinstance(value, bool):
            raise StudyError(f"{where}: {key} = {str(value)[:60]}; expected {what}")
    for key in REQUIRED:
        if key not in raw:
            raise StudyError(f"{where}: no {key!r}; expected {STUDY_KEYS[key][1]}")
    if "points" not in raw and "grids" not in raw:
        raise StudyError(f"{where}: no points and no grids; expected at least one")
    if raw.get("until", "delivered") not in UNTIL:
        raise StudyError(f"{where}: until = {raw['until']!r}; expected {' or '.join(UNTIL)}")
    if raw.get("seeds", 20) < 1:
        raise StudyError(f"{where}: seeds = {raw['seeds']}; expected a count of seeds, 1..")
    from sim_backend.sweep import grid_points
    points: list[Point] = []
    for g in raw.get("grids", ()):
        if not (isinstance(g, tuple) and len(g) == 2 and isinstance(g[0], str)):
            raise StudyError(f"{where}: grid {str(g)[:60]}; expected (experiment, "
                             "((key, (v1, v2, ...)), ...))")
        grid = {}
        for key, values in _pairs(g[1], where, f"grid {g[0]!r}"):
            if not isinstance(values, tuple) or not values:
                raise StudyError(f"{where}: grid {g[0]!r}: {key} = {values!r}; expected a "
                                 "tuple of values")
            grid[key] = [_value(kinds, key, v, f"{where} grid {g[0]!r}") for v in values]
        try:
            points += grid_points(grid, g[0])
        except ScenarioError as err:
            raise StudyError(f"{where}: grid {g[0]!r}: {err}") from None
    for p in raw.get("points", ()):
        if not (isinstance(p, tuple) and len(p) == 2 and isinstance(p[0], str)):
            raise StudyError(f"{where}: point {str(p)[:60]}; expected (experiment, "
                             "((key, value), ...))")
        pairs = _pairs(p[1], where, f"point {p[0]!r}")
        points.append(Point(p[0], tuple((k, _value(kinds, k, v, f"{where} point {p[0]!r}"))
                                        for k, v in pairs)))
    overrides = tuple((k, _value(kinds, k, v, f"{where} set"))
                      for k, v in _pairs(raw.get("set", ()), where, "set"))
    figures = tuple(_figure(f, where) for f in raw["figures"])
    names = [f["name"] for f in figures]
    dup = next((n for i, n in enumerate(names) if n in names[:i]), None)
    if dup:
        raise StudyError(f"{where}: figure {dup!r} is declared twice")
    return Study(behaviour, raw["name"], raw["about"], raw.get("seeds", 20),
                 raw.get("until", "delivered"), overrides, tuple(points), figures)


@functools.lru_cache(maxsize=None)
def of(behaviour: str) -> dict[str, Study]:
    """The behaviour's studies by name, checked (none without a studies.py)."""
    from sim_backend import registry
    try:
        raw = registry.load(behaviour).studies
    except registry.BehaviourError as err:
        raise StudyError(str(err)) from None
    if not isinstance(raw, tuple):
        raise StudyError(f"behaviour {behaviour!r}: studies.py STUDIES is a "
                         f"{type(raw).__name__}; expected a tuple of studies")
    kinds = _kinds(behaviour)
    out: dict[str, Study] = {}
    for r in raw:
        s = _study(behaviour, r, kinds)
        if s.name in out:
            raise StudyError(f"behaviour {behaviour!r}: studies.py declares study "
                             f"{s.name!r} twice")
        out[s.name] = s
    return out


def get(behaviour: str, name: str) -> Study:
    """One study of the behaviour; StudyError listing its studies when it has
    none of that name."""
    studies = of(behaviour)
    if name not in studies:
        have = ", ".join(studies) or "none (no studies.py in its folder)"
        raise StudyError(f"study {name!r}: behaviour {behaviour!r} declares no such study; "
                         f"its studies: {have}")
    return studies[name]


def check(study: Study, base: Any = None, overrides: dict[str, Any] | None = None) -> None:
    """Every point a valid scenario (ScenarioError naming the study and the
    point)."""
    from sim_backend import sweep
    ovr = {**dict(study.overrides), **dict(overrides or {})}
    for pt in study.points:
        try:
            sweep.validate_points([pt], base, ovr)
        except ScenarioError as err:
            text = ", ".join(f"{k}={v}" for k, v in pt.params)
            raise StudyError(f"behaviour {study.behaviour!r} study {study.name!r}: point "
                             f"{pt.experiment!r} ({text}): {err}") from None


def draw(study: Study, rows: Sequence[dict], out: Path) -> list[Path]:
    """Every figure of the study the rows hold data for, out/NAME.png."""
    from sim_backend import plots
    paths = []
    for f in study.figures:
        fn = getattr(plots, FIGURES[f["kind"]][0])
        p = fn(rows, f, out / f"{f['name']}.png")
        if p:
            paths.append(p)
    return paths


def main(argv: Sequence[str] | None = None) -> int:
    """`python -m sim_backend.studies BEHAVIOUR STUDY SWEEP_CSV OUTDIR`: draw
    a study's figures again from its sweep.csv."""
    import sys
    from sim_backend.sweep import read_csv
    args = list(sys.argv[1:] if argv is None else argv)
    if len(args) != 4:
        print("usage: python -m sim_backend.studies BEHAVIOUR STUDY SWEEP_CSV OUTDIR",
              file=sys.stderr)
        return 2
    try:
        study = get(args[0], args[1])
        for p in draw(study, read_csv(Path(args[2])), Path(args[3])):
            print(p)
    except (ScenarioError, OSError) as err:
        print(f"studies: {err}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
