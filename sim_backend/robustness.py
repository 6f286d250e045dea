"""Fault runs, world-level: which runs could deliver at all
(with_feasible), the table of a fault study's rates (fault_table, drawn by
sim_backend/plots.rates_plot; the thesis's faults study is in its
studies.py), why a run did not deliver (diagnose, why_table) and the
figures of docs/extensions.md and docs/movement-models.md.

`python -m sim_backend.robustness why STUDY POINT SEEDS [KEY=VALUE ...]`
says why each run of one point of a study ended (e.g. `why faults goal 40`,
the thesis's goal mix over seeds 1..40; KEY=VALUE changes a scenario key).

`python -m sim_backend.robustness models SWEEP_CSV FACTOR OUT.png` draws the
convergence and first-touch times of a categorical grid (movement models,
a choice parameter); `... trajectories OUT.png [BEHAVIOUR]` one trajectory of each of
the behaviour's movement models.
"""

from __future__ import annotations

import statistics
import sys
from pathlib import Path
from typing import Any, Sequence

from sim_backend.plots import _save

def _num(v: Any) -> float | None:
    if v in (None, "", "None"):
        return None
    return float(v)


def _value(v: Any) -> Any:
    """A CSV cell back to its type (rows from sweep() already have theirs)."""
    if not isinstance(v, str):
        return v
    if v == "None":
        return None
    if v in ("True", "False"):        # a boolean key (wrap)
        return v == "True"
    for kind in (int, float):
        try:
            return kind(v)
        except ValueError:
            pass
    return v


def with_feasible(rows: Sequence[dict]) -> list[dict]:
    """Rows with `feasible` (docs/extensions.md): the robots that never die and
    may claim can lift the object (faults.feasible), and the run did not end
    with the host finding no way home round the obstacles it knows (the
    map's, and when its host drops lost holders the cells of the holders that died: an object
    pinned by dead robots cannot be delivered by anyone)."""
    from sim_backend import faults
    from sim_backend.scenario import validate
    from sim_backend.sweep import row_keys
    out = []
    for r in rows:
        raw = {k: v for k, v in r.items() if k in row_keys(r) and k not in ("name", "description")
               and v not in (None, "", "()", ())}
        sc = validate({k: _value(v) for k, v in raw.items()})
        out.append({**r, "feasible": faults.feasible(sc, int(r["seed"]))
                    and r.get("outcome") != NO_PATH})
    return out


def fault_table(rows: Sequence[dict], reference: str | None = None
                ) -> dict[str, list[tuple[float, int, int, float | None]]]:
    """experiment -> [(rate, feasible runs, delivered of those, median home
    tick)]: each experiment is named after the fault key it varies; the
    reference experiment (a mix) has one entry at rate -1."""
    table: dict[str, dict[float, list[dict]]] = {}
    for r in with_feasible(rows):
        exp = r["experiment"]
        rate = float(r[exp]) if exp != reference else -1.0
        table.setdefault(exp, {}).setdefault(rate, []).append(r)
    out: dict[str, list[tuple[float, int, int, float | None]]] = {}
    for exp, by in table.items():
        for rate in sorted(by):
            rs = [r for r in by[rate] if r["feasible"]]
            got = [r for r in rs if str(r["delivered"]) in ("True", "true", "1")]
            homes = [h for h in (_num(r["home_tick"]) for r in got) if h is not None]
            med = statistics.median(homes) if homes else None
            out.setdefault(exp, []).append((rate, len(rs), len(got), med))
    return out


def category_plot(rows: Sequence[dict], factor: str, path: Path) -> Path:
    """First touch and convergence per value of a categorical factor (box plots;
    runs that never converged are counted in the label)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    values: list[str] = []
    for r in rows:
        if r[factor] not in values:
            values.append(r[factor])
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for ax, col, title in ((axes[0], "found_tick", "first touch"),
                           (axes[1], "converged_tick", "convergence")):
        data, labels = [], []
        for v in values:
            rs = [r for r in rows if r[factor] == v]
            got = [_num(r[col]) for r in rs if _num(r[col]) is not None]
            data.append(got or [float("nan")])
            labels.append(f"{v}\n{len(got)}/{len(rs)}")
        ax.boxplot(data, showfliers=False)
        ax.set_xticks(range(1, len(labels) + 1), labels, fontsize=8)
        ax.set_ylabel("tick")
        ax.set_title(title)
    fig.suptitle(f"{factor}: ticks to first touch and to convergence (n reached/runs)")
    fig.tight_layout()
    return _save(fig, path, dpi=110)


def trajectories_plot(path: Path, seed: int = 3, ticks: int = 150,
                      behaviour: str | None = None) -> Path:
    """One robot's first `ticks` ticks under each of the behaviour's
    movement models (spec.MODELS, set through the parameter that names one)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from sim_backend import params
    from sim_backend.engine import Engine
    from sim_backend.errors import ScenarioError
    from sim_backend.scenario import DEFAULT_BEHAVIOUR, validate
    from sim_backend.world import World
    behaviour = behaviour or DEFAULT_BEHAVIOUR
    key = next((p for p in params.declared(behaviour) if p.codes), None)
    if key is None:
        raise ScenarioError(f"behaviour {behaviour!r}: no parameter names one of its "
                            "spec.MODELS; no movement models to draw")
    fig, axes = plt.subplots(1, len(key.choices), figsize=(3.2 * len(key.choices), 3.4),
                             squeeze=False)
    for ax, model in zip(axes[0], key.choices):
        e = Engine(validate({"behaviour": behaviour, key.name: model, "maxTicks": ticks}), seed,
                   record_trajectories=True)
        r = e.run()
        xs = [f[0][0] / 256 for f in r.trajectories]
        ys = [f[1][0] / 256 for f in r.trajectories]
        start = World(r.scenario, seed).object_cells      # where the object starts
        cx = [c[0] for c in start]
        cy = [c[1] for c in start]
        ax.scatter(cx, cy, s=12, c="gold", marker="s")
        ax.plot(xs, ys, "-", lw=0.8)
        ax.plot(xs[:1], ys[:1], "go", ms=4)
        ax.set_xlim(-18, 18)
        ax.set_ylim(-18, 18)
        ax.set_aspect("equal")
        ax.set_title(f"{model} (node 1, {len(xs)} ticks)", fontsize=9)
    fig.tight_layout()
    return _save(fig, path, dpi=110)


# why a run of a fault scenario did not deliver (diagnose)
NO_PATH = "no path home"           # the thesis coordinator's stop reason
WHY_ORDER = ("delivered", "infeasible", "no path home", "never converged", "leader dead", "power lost",
             "defiant holder", "blocked by dead robots", "stuck")


def diagnose(r: Any) -> str:
    """Why a finished run (engine.RunResult) of a fault scenario ended as it
    did, one of WHY_ORDER: infeasible (faults.feasible is false), no path
    home (the host found none round the obstacles it knows), never
    converged, leader dead (the leader died after convergence and the
    transport waits for its pose), power lost (the live holders' power is
    below the weight), defiant holder (a live holder ignores the host's
    TRANSPORT, so the object it grips never moves), blocked by dead robots (a dead robot stands next to
    the object or a carrier when it stopped moving) or stuck (anything
    else that kept it from moving: walls, live robots, no path)."""
    from firmware_logic.fixedpoint import patch
    from sim_backend import faults
    sc, c, w = r.scenario, r.coordinator, r.world
    if r.delivered:
        return "delivered"
    if not faults.feasible(sc, r.seed):
        return "infeasible"
    if c.measures().get("outcome") == NO_PATH:
        return NO_PATH
    if c.converged_tick < 0:
        return "never converged"
    die = faults.plan(sc, r.seed)[0]
    dead = {i + 1 for i, d in enumerate(die) if d <= r.ticks}
    lost = set(getattr(c, "lost", ()))
    if c.leader in dead and c.leader not in lost:
        return "leader dead"
    live = sum(t.power for t in c.touches if t.node not in dead)
    if live < sc.weight_centi:
        return "power lost"
    flags = faults.plan(sc, r.seed)[3]
    if any(flags[t.node - 1] & faults.IGNORE_HOST for t in c.touches if t.node not in dead):
        return "defiant holder"
    near = set()
    for x, y in list(w.object_cells) + c._carriers_now():
        for a in (-1, 0, 1):
            for b in (-1, 0, 1):
                near.add((x + a, y + b))
    if any((patch(w.xs[i - 1]), patch(w.ys[i - 1])) in near for i in dead):
        return "blocked by dead robots"
    return "stuck"


def why_table(raw: dict, seeds: Sequence[int]) -> dict[str, list[int]]:
    """Run the scenario `raw` on the reference engine for each seed, until
    delivered or maxTicks: diagnosis -> seeds."""
    from sim_backend.engine import Engine
    from sim_backend.scenario import validate
    sc = validate(raw)
    out: dict[str, list[int]] = {}
    for seed in seeds:
        out.setdefault(diagnose(Engine(sc, seed).run()), []).append(seed)
    return out


def study_point(study: str, point: str, changes: dict[str, Any]) -> dict:
    """The scenario of one point of a study (its overrides, then the
    point's keys, then `changes`; changes may name the behaviour, default
    the thesis)."""
    from sim_backend import studies
    from sim_backend.scenario import DEFAULT_BEHAVIOUR
    behaviour = str(changes.get("behaviour", DEFAULT_BEHAVIOUR))
    st = studies.get(behaviour, study)
    pts = [p for p in st.points if p.experiment == point]
    if len(pts) != 1:
        raise studies.StudyError(
            f"study {study!r}: {len(pts)} points are named {point!r}; expected one of "
            f"{', '.join(dict.fromkeys(p.experiment for p in st.points))}")
    return {**dict(st.overrides), **pts[0].as_dict(), **changes}


def main(argv: list[str]) -> int:
    import csv
    if argv[:1] == ["models"] and len(argv) == 4:
        rows = list(csv.DictReader(open(argv[1])))
        print(category_plot(rows, argv[2], Path(argv[3])))
        return 0
    if argv[:1] == ["trajectories"] and len(argv) in (2, 3):
        print(trajectories_plot(Path(argv[1]), behaviour=argv[2] if len(argv) == 3 else None))
        return 0
    if argv[:1] == ["why"] and len(argv) >= 4:
        # a point of a study (e.g. the thesis's faults study's goal mix) with
        # the study's settings, seeds 1..N, KEY=VALUE changes: why each run ended
        changes = {}
        for kv in argv[4:]:
            k, _, v = kv.partition("=")
            changes[k] = _value(v)
        got = why_table(study_point(argv[1], argv[2], changes), range(1, int(argv[3]) + 1))
        for why in WHY_ORDER:
            if why in got:
                print(f"{why:24s} {len(got[why]):3d}  seeds {got[why]}")
        return 0
    print("usage: python -m sim_backend.robustness models CSV FACTOR OUT.png | "
          "trajectories OUT.png [BEHAVIOUR] | why STUDY POINT SEEDS [KEY=VALUE ...]",
          file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
