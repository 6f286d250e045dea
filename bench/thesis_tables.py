"""The smaller-sample tables of docs/thesis-reproduction.md (Graph 1 and
Graphs 2-4 under three rule sets, the fieldDefiance-0 stalls, the
sensitivity of the unsourced base values, the two activations), the
option effects and world edges of docs/tick-semantics.md (tables and the
figures their notes quote), the movement models' convergence of
docs/movement-models.md and the swarm sizes, obstacles on and off and
static and dynamic field of docs/extensions.md, each
rendered from a committed JSON of per-point statistics, so a changed
default cannot leave a stale figure in the text: a test checks that each
table between its markers is what this script renders from
bench/thesis_tables.json.

Reads the sweep.csv of each named run (the commands in RUNS), reduces it
to per-point statistics (runs, stalled, delivered; the median and mean of
convergence in go iterations, `converged_tick`, and in robot moves,
`converged_moves`, over the converged runs; the transport, `home_tick -
converged_tick`, over the delivered runs) and writes them as JSON:

    .venv/bin/python bench/thesis_tables.py T-sync=DIR/sweep.csv T-ask=... \
        --json bench/thesis_tables.json [--wall NAME=SECONDS ...] [--docs]
    .venv/bin/python bench/thesis_tables.py Sizes=DIR/sweep.csv --json bench/thesis_tables.json \
        --update [--docs]     # replaces the runs given, keeps the others
    .venv/bin/python bench/thesis_tables.py --from-json bench/thesis_tables.json [--docs]

--docs puts every table between its markers in its doc (TABLES: the
options table is docs/tick-semantics.md's); without it the tables are
printed. The stall table's last row is the 150-seed reproduction
of record, read from bench/thesis_claims.json.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import statistics
import sys
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CLAIMS = ROOT / "bench" / "thesis_claims.json"

# the columns that tell the thesis study's points apart
STUDY_KEYS = ("experiment", "movementModel", "fieldDefiance", "sigRadius", "rPower", "object",
              "objectWeight")
# each run: its command (every one ran with `--engine soa --executor inline
# --no-plots --out DIR` added) and the columns that name its points
RUNS = {
    "T-sync": ("touchswarm sweep --thesis --activation sync --seeds 20", STUDY_KEYS),
    "T-ask": ("touchswarm sweep --thesis --activation netlogo --seeds 20", STUDY_KEYS),
    "T-thesis": ("touchswarm sweep --thesis --scenario netlogo --seeds 20", STUDY_KEYS),
    "Sens-span": ("touchswarm sweep --grid robotVisionSpan=15,45,90,180 --grid movementModel=ant "
                  "--seeds 20 --until converged --set maxTicks=5000",
                  ("movementModel", "robotVisionSpan")),
    "Sens-weight": ("touchswarm sweep --grid objectWeight=3,5,8 --grid movementModel=firefly,ant "
                    "--seeds 20 --until converged --set maxTicks=5000",
                    ("movementModel", "objectWeight")),
    "Sens-world": ("touchswarm sweep --grid worldSize=18,22,26 --grid movementModel=firefly,ant "
                   "--seeds 20 --until converged --set maxTicks=5000",
                   ("movementModel", "worldSize")),
    "S-act": ("touchswarm sweep --grid activation=sync,netlogo --grid fieldDefiance=0,2 "
              "--grid movementModel=firefly,ant --seeds 30 --set maxTicks=5000",
              ("activation", "movementModel", "fieldDefiance")),
    "S-thesis": ("touchswarm sweep --scenario netlogo --grid fieldDefiance=0,2 "
                 "--grid movementModel=firefly,ant --seeds 30 --set maxTicks=5000",
                 ("activation", "movementModel", "fieldDefiance")),
    "S-wrap": ("touchswarm sweep --grid wrap=false,true --grid movementModel=firefly,ant "
               "--grid activation=sync,netlogo --seeds 20 --set maxTicks=5000",
               ("movementModel", "activation", "wrap")),
    "Models": ("touchswarm sweep --grid movementModel=firefly,ant,levy,moth,frog --seeds 50 "
               "--until converged --set maxTicks=5000", ("movementModel",)),
    "Moth": ("touchswarm sweep --grid movementModel=moth --seeds 50 --set maxTicks=5000",
             ("movementModel",)),
    "O-three": ("touchswarm sweep --grid signalMode=patch,netlogo --grid uphillTies=ordered,netlogo "
                "--grid leaderField=off,netlogo --grid fieldDefiance=0,2 "
                "--grid movementModel=firefly,ant --seeds 30 --set maxTicks=5000",
                ("signalMode", "uphillTies", "leaderField", "movementModel", "fieldDefiance")),
    "O-two": ("touchswarm sweep --grid starts=redraw,netlogo --grid arrival=within4,netlogo "
              "--grid fieldDefiance=0,2 --grid movementModel=firefly,ant --seeds 30 "
              "--set maxTicks=5000",
              ("starts", "arrival", "movementModel", "fieldDefiance")),
    "O-five": ("touchswarm sweep --set signalMode=netlogo --set uphillTies=netlogo "
               "--set leaderField=netlogo --set starts=netlogo --set arrival=netlogo "
               "--grid fieldDefiance=0,2 --grid movementModel=firefly,ant --seeds 30 "
               "--set maxTicks=5000", ("movementModel", "fieldDefiance")),
    "Sizes": ("touchswarm sweep --preset sizes", ("agents", "worldSize")),
    "Sizes-block": ("touchswarm sweep --preset sizes --set crowd=block", ("agents", "worldSize")),
    "Field": ("touchswarm sweep --preset field", ("agents", "field", "crowd")),
    # sweep.csv has no obstacles column: the point's text names the wall
    "Obstacles": ("touchswarm sweep --preset obstacles", ("point",)),
}
# the runs docs/extensions.md's swarm-size, field and obstacles tables read;
# they are not the thesis study's, so the thesis runs table leaves them out
SIZE_RUNS = ("Sizes", "Sizes-block")
FIELD_RUNS = ("Field",)
OBSTACLE_RUNS = ("Obstacles",)
MODELS = ("firefly", "ant")
# each table and the doc that carries it
TABLES = {t: "docs/thesis-reproduction.md" for t in ("runs", "sensitivity", "graph1", "stalls",
                                                      "graphs234", "activation")}
TABLES["options"] = TABLES["options-notes"] = "docs/tick-semantics.md"
TABLES["wrap"] = TABLES["wrap-notes"] = "docs/tick-semantics.md"
TABLES["sizes"] = TABLES["field"] = TABLES["obstacles"] = "docs/extensions.md"
TABLES["models"] = "docs/movement-models.md"


def _f(v):
    return None if v in (None, "") else float(v)


def _key(v: str) -> str:
    """A point's value as the JSON keeps it: numbers without a trailing .0."""
    try:
        return f"{float(v):g}"
    except ValueError:
        return v


def _stat(vals: list[float]) -> tuple[float | None, float | None]:
    if not vals:
        return None, None
    return float(statistics.median(vals)), round(statistics.fmean(vals), 3)


def _spread(vals: list[float]) -> dict:
    """The least, the greatest and the sample sd (None below two values)."""
    return {"min": min(vals) if vals else None, "max": max(vals) if vals else None,
            "sd": round(statistics.stdev(vals), 1) if len(vals) > 1 else None}


def reduce(name: str, rows: list[dict]) -> list[dict]:
    """One entry per point of run `name`, in the sweep's order."""
    keys = RUNS[name][1]
    groups: dict[tuple, list[dict]] = defaultdict(list)
    for r in rows:
        groups[tuple(_key(r[k]) for k in keys)].append(r)
    out = []
    for key, rs in groups.items():
        conv = [r for r in rs if _f(r["converged_tick"]) is not None]
        home = [r for r in conv if r["delivered"] in ("True", "true", "1")]
        it_med, it_mean = _stat([_f(r["converged_tick"]) for r in conv])
        mv_med, mv_mean = _stat([_f(r["converged_moves"]) for r in conv])
        tr_med, tr_mean = _stat([_f(r["home_tick"]) - _f(r["converged_tick"]) for r in home
                                 if _f(r["home_tick"]) is not None])
        found = [_f(r["found_tick"]) for r in rs if _f(r["found_tick"]) is not None]
        homes = [_f(r["home_tick"]) for r in home if _f(r["home_tick"]) is not None]
        its = _spread([_f(r["converged_tick"]) for r in conv])
        hs = _spread(homes)
        ious = [v for v in (_f(r.get("shape_iou")) for r in rs) if v is not None]
        out.append({"run": name, **dict(zip(keys, key)), "n": len(rs),
                    "stalled": len(rs) - len(conv), "delivered": len(home),
                    "found_median": _stat(found)[0], "found_mean": _stat(found)[1],
                    "home_median": _stat(homes)[0],
                    "it_median": it_med, "it_mean": it_mean,
                    "mv_median": mv_med, "mv_mean": mv_mean,
                    "transport_median": tr_med, "transport_mean": tr_mean,
                    "it_min": its["min"], "it_max": its["max"], "it_sd": its["sd"],
                    "home_min": hs["min"], "home_max": hs["max"],
                    "iou_mean": round(statistics.fmean(ious), 3) if ious else None})
    return out


# -- rendering --------------------------------------------------------------------

def _n(v: float | None) -> str:
    return "-" if v is None else f"{v:.0f}"


def _m(v: float | None) -> str:
    """A median: halves kept, as the median of an even count gives them."""
    return "-" if v is None else f"{v:g}"


def _find(points: list[dict], run: str, **kv) -> dict:
    for p in points:
        if p["run"] == run and all(str(p.get(k)) == str(v) for k, v in kv.items()):
            return p
    raise KeyError(f"{run} {kv}: no such point")


def _runs(data: dict) -> list[str]:
    out = ["| name | command | n | wall (s) |", "|---|---|---|---|"]
    for name, meta in data["meta"]["runs"].items():
        if name in SIZE_RUNS + FIELD_RUNS + OBSTACLE_RUNS:
            continue
        out.append(f"| **{name}** | `{meta['command']}` | {meta['points']} points x "
                   f"{meta['seeds']} | {meta.get('wall_s', '-')} |")
    return out


def _sensitivity(pts: list[dict]) -> list[str]:
    def cell(run, model, key, v):
        p = _find(pts, run, movementModel=model, **{key: v})
        s = f"{_m(p['it_median'])} ({_n(p['it_mean'])})"
        if p["stalled"]:
            s += f", {p['stalled']} stalled"
        return f"**{s}**" if v in BASE.get(key, ()) else s
    out = ["| value varied (others at the base) | firefly | ant |", "|---|---|---|"]
    spans = ("15", "45", "90", "180")
    out.append("| robotVisionSpan " + " / ".join(f"**{v}**" if v == "45" else v for v in spans)
               + " | no effect (firefly ignores it) | "
               + " / ".join(cell("Sens-span", "ant", "robotVisionSpan", v) for v in spans) + " |")
    for run, key, label, vals in (("Sens-weight", "objectWeight",
                                   "objectWeight {} (robots required {})", ("3", "5", "8")),
                                  ("Sens-world", "worldSize", "worldSize {} (arena -w..w)",
                                   ("18", "22", "26"))):
        shown = " / ".join(f"**{v}**" if v in BASE[key] else v for v in vals)
        label = label.format(shown, " / ".join(vals)) if "required" in label else \
            label.format(shown)
        out.append(f"| {label} | "
                   + " | ".join(" / ".join(cell(run, m, key, v) for v in vals) for m in MODELS)
                   + " |")
    return out


BASE = {"robotVisionSpan": ("45",), "objectWeight": ("5",), "worldSize": ("18",)}
THREE = ("T-sync", "T-ask", "T-thesis")


def _graph1(pts: list[dict]) -> list[str]:
    out = ["| fieldDefiance | " + " | ".join(f"{m} {r}" for m in MODELS for r in THREE) + " |",
           "|---|" + "---|" * 6]
    for fd in ("0", "1", "2", "4", "6", "8", "10"):
        cells = []
        for m in MODELS:
            for r in THREE:
                p = _find(pts, r, experiment="graph1", movementModel=m, fieldDefiance=fd)
                s = _n(p["it_mean"]) if r == "T-sync" else \
                    f"{_n(p['it_mean'])} / {_n(p['mv_mean'])}"
                if p["stalled"]:
                    s += f" ({p['stalled']} stalled)"
                cells.append(s)
        out.append(f"| {fd} | " + " | ".join(cells) + " |")
    return out


def _stalls(pts: list[dict]) -> list[str]:
    out = ["| run | n | firefly stalled | ant stalled |", "|---|---|---|---|"]
    for label, run, kv in (("T-sync (sync, until converged)", "T-sync", {"experiment": "graph1"}),
                           ("T-ask (netlogo activation, our rules)", "T-ask",
                            {"experiment": "graph1"}),
                           ("T-thesis (`--scenario netlogo`, every option the thesis's)",
                            "T-thesis", {"experiment": "graph1"}),
                           ("S-act, sync (until delivered)", "S-act", {"activation": "sync"}),
                           ("S-act, netlogo activation", "S-act", {"activation": "netlogo"}),
                           ("S-thesis (`--scenario netlogo`, until delivered)", "S-thesis", {})):
        ps = [_find(pts, run, movementModel=m, fieldDefiance="0", **kv) for m in MODELS]
        out.append(f"| {label} | {ps[0]['n']} | {ps[0]['stalled']} | {ps[1]['stalled']} |")
    claims = json.loads(CLAIMS.read_text())
    ps = [next(p for p in claims["points"] if p["experiment"] == "graph1" and p["series"] == m
               and p["x"] == 0) for m in MODELS]
    out.append(f"| T-thesis150 (`--scenario netlogo`, the claims table) | {ps[0]['n']} | "
               f"{ps[0]['stalled']} | {ps[1]['stalled']} |")
    return out


def _graphs234(pts: list[dict]) -> list[str]:
    out = ["| Graph | value | " + " | ".join(f"{m} {r}" for m in MODELS for r in THREE) + " |",
           "|---|---|" + "---|" * 6]
    rows = [("2", f"sigRadius {v}", "graph2", {"sigRadius": v}) for v in ("1", "2", "3", "5", "7",
                                                                          "9")]
    rows += [("3", f"rPower {v} ({q} required)" if v == "0.5" else f"rPower {v} ({q})", "graph3",
              {"rPower": v}) for v, q in (("0.5", 10), ("0.75", 7), ("1", 5), ("1.25", 4),
                                          ("2", 3), ("2.5", 2), ("5", 1))]
    for g, label, exp, kv in rows:
        cells = []
        for m in MODELS:
            for r in THREE:
                p = _find(pts, r, experiment=exp, movementModel=m, **kv)
                s = _n(p["it_mean"])
                if p["stalled"]:
                    s += f" ({p['stalled']} stalled)"
                cells.append(s)
        out.append(f"| {g} | {label} | " + " | ".join(cells) + " |")
    return out


def _activation(pts: list[dict]) -> list[str]:
    out = ["| rules | activation | model | fD 0: stalled / delivered | fD 0: median go iterations "
           "(moves) | fD 2: stalled / delivered | fD 2: median (mean) go iterations | fD 2: "
           "median (mean) robot moves | fD 2: transport median (mean) |",
           "|---|---|---|---|---|---|---|---|---|"]
    for rules, run, act in (("default", "S-act", "sync"), ("default", "S-act", "netlogo"),
                            ("thesis (`--scenario netlogo`)", "S-thesis", "netlogo")):
        for m in MODELS:
            z = _find(pts, run, activation=act, movementModel=m, fieldDefiance="0")
            t = _find(pts, run, activation=act, movementModel=m, fieldDefiance="2")
            out.append(f"| {rules} | {act} | {m} | {z['stalled']} / {z['delivered']} | "
                       f"{_m(z['it_median'])} ({_n(z['mv_median'])}) | "
                       f"{t['stalled']} / {t['delivered']} | "
                       f"{_m(t['it_median'])} ({_n(t['it_mean'])}) | "
                       f"{_n(t['mv_median'])} ({_n(t['mv_mean'])}) | "
                       f"{_m(t['transport_median'])} ({_n(t['transport_mean'])}) |")
    return out


def _options(pts: list[dict]) -> list[str]:
    out = ["| option on | model | fD 0: stalled / delivered (of 30) | fD 0: median ticks | "
           "fD 2: stalled / delivered | fD 2: median (mean) ticks |",
           "|---|---|---|---|---|---|"]
    three = {"signalMode": "patch", "uphillTies": "ordered", "leaderField": "off"}
    rows = [("none (defaults)", "O-three", three)]
    rows += [(f"`{k}`", "O-three", {**three, k: "netlogo"}) for k in three]
    rows += [("the three above", "O-three", {k: "netlogo" for k in three}),
             ("`starts`", "O-two", {"starts": "netlogo", "arrival": "within4"}),
             ("`arrival`", "O-two", {"starts": "redraw", "arrival": "netlogo"}),
             ("all five", "O-five", {})]
    for label, run, kv in rows:
        for m in MODELS:
            z = _find(pts, run, movementModel=m, fieldDefiance="0", **kv)
            t = _find(pts, run, movementModel=m, fieldDefiance="2", **kv)
            out.append(f"| {label} | {m} | {z['stalled']} / {z['delivered']} | "
                       f"{_m(z['it_median'])} | {t['stalled']} / {t['delivered']} | "
                       f"{_m(t['it_median'])} ({_n(t['it_mean'])}) |")
    return out


def _wrap(pts: list[dict]) -> list[str]:
    out = ["| model | activation | wrap | first touch: median tick | converged (of 20) | "
           "convergence: median tick (mean) | delivered (of 20) | delivery: median tick |",
           "|---|---|---|---|---|---|---|---|"]
    for m in MODELS:
        for act in ("sync", "netlogo"):
            for wrap, label in (("False", "off"), ("True", "on")):
                p = _find(pts, "S-wrap", movementModel=m, activation=act, wrap=wrap)
                out.append(f"| {m} | {act} | {label} | {_m(p['found_median'])} | "
                           f"{p['n'] - p['stalled']} | {_m(p['it_median'])} ({_n(p['it_mean'])}) | "
                           f"{p['delivered']} | {_m(p['home_median'])} |")
    return out


def _models(pts: list[dict]) -> list[str]:
    out = ["| model | converged | first touch median (mean) | convergence median (mean) |",
           "|---|---|---|---|"]
    for m in ("firefly", "ant", "levy", "moth", "frog"):
        p = _find(pts, "Models", movementModel=m)
        out.append(f"| {m} | {p['n'] - p['stalled']}/{p['n']} | {_m(p['found_median'])} "
                   f"({p['found_mean']:.1f}) | {_m(p['it_median'])} ({p['it_mean']:.1f}) |")
    p = _find(pts, "Moth", movementModel="moth")
    out += ["", "| model (until delivered) | delivered | delivery: median tick |", "|---|---|---|",
            f"| moth | {p['delivered']}/{p['n']} | {_m(p['home_median'])} |"]
    return out


def _options_notes(pts: list[dict]) -> list[str]:
    """The figures the options table's notes quote, from the same points."""
    three = {"signalMode": "patch", "uphillTies": "ordered", "leaderField": "off"}
    faithful = {k: "netlogo" for k in three}

    def stalled(run: str, m: str, **kv) -> str:
        p = _find(pts, run, movementModel=m, fieldDefiance="0", **kv)
        return f"{p['stalled']}/{p['n']}"

    def two(m: str, fd: str, starts: str, arrival: str) -> dict:
        return _find(pts, "O-two", movementModel=m, fieldDefiance=fd, starts=starts,
                     arrival=arrival)
    base = {m: two(m, "2", "redraw", "within4") for m in MODELS}
    starts = two("firefly", "2", "netlogo", "within4")
    arrive = {m: two(m, "2", "redraw", "netlogo") for m in MODELS}
    o_runs = [p for p in pts if p["run"] in ("O-three", "O-two", "O-five")]
    every = all(p["n"] - p["stalled"] == p["delivered"] for p in o_runs)
    return [
        "- **fieldDefiance 0 stalls with and without the NetLogo rules.** An",
        "  earlier independent *asynchronous* model reported 5/30 -> 17/30 stalled",
        "  (ant) when Signal centring, ties and `field 10` are made faithful. In",
        f"  this synchronous engine the three together give {stalled('O-three', 'ant', **faithful)}"
        " stalled (ant)",
        f"  against {stalled('O-three', 'ant', **three)} with our rules, and "
        f"{stalled('O-three', 'firefly', **faithful)} against "
        f"{stalled('O-three', 'firefly', **three)} (firefly). With every option",
        "  the thesis's (`--scenario netlogo`, the activation and the wrapping world",
        f"  too), {stalled('S-thesis', 'ant', activation='netlogo')} (ant) and "
        f"{stalled('S-thesis', 'firefly', activation='netlogo')} (firefly) stall; NetLogo's",
        f"  `ask` alone gives {stalled('S-act', 'ant', activation='netlogo')} and "
        f"{stalled('S-act', 'firefly', activation='netlogo')}"
        " (docs/thesis-reproduction.md, runs S-act and S-thesis), and the",
        "  independent reading of Appendix A there (bench/appendix_a.py) stalls as",
        "  often as `--scenario netlogo` at 200 seeds.",
        "- At fieldDefiance 2, `starts` for the firefly: median "
        f"{_m(starts['it_median'])} against {_m(base['firefly']['it_median'])} ticks"
        " (why is not examined).",
        "- `arrival = \"netlogo\"`: median ticks from convergence to delivery at",
        f"  fieldDefiance 2: firefly {_m(arrive['firefly']['transport_median'])} against "
        f"{_m(base['firefly']['transport_median'])}, ant "
        f"{_m(arrive['ant']['transport_median'])} against "
        f"{_m(base['ant']['transport_median'])} (the nearest holder,",
        "  not the nearest segment, must reach home); delivered at fieldDefiance 2:",
        f"  firefly {arrive['firefly']['delivered']} of {arrive['firefly']['n']}, ant "
        f"{arrive['ant']['delivered']} of {arrive['ant']['n']}.",
        "- Every run that converged delivered, at fieldDefiance 0 too." if every else
        "- Not every run that converged delivered (the delivered columns)."]


def _wrap_notes(pts: list[dict]) -> list[str]:
    """The figures the wrap table's notes quote, from the same points."""
    def p(m: str, act: str, wrap: str) -> dict:
        return _find(pts, "S-wrap", movementModel=m, activation=act, wrap=wrap)
    pairs = [(p(m, a, "True"), p(m, a, "False")) for m in MODELS for a in ("sync", "netlogo")]
    same_touch = all(on["found_median"] == off["found_median"] for on, off in pairs)
    moves = [abs(on["it_median"] - off["it_median"]) for on, off in pairs]
    all_conv = all(q["stalled"] == 0 for pair in pairs for q in pair)
    all_home = all(q["delivered"] == q["n"] for pair in pairs for q in pair)

    def vs(m: str, act: str, key: str) -> str:
        f = _m if key == "it_median" else _n
        return f"{f(p(m, act, 'True')[key])} against {f(p(m, act, 'False')[key])}"

    def sd(m: str, of_median: bool = False) -> str:
        """The sd over the rows of model m, or a median's standard error
        (about 1.25 sd / sqrt(runs) for a roughly normal spread)."""
        sds = [q["it_sd"] * (1.25 / (q["n"] - q["stalled"]) ** 0.5 if of_median else 1)
               for on, off in pairs for q in (on, off)
               if q["movementModel"] == m and q.get("it_sd") is not None]
        return f"{min(sds):.0f}-{max(sds):.0f}" if sds else "-"
    return [
        "- **Time to first touch: "
        + ("unchanged** (the same median in every row)." if same_touch else
           "changed** in some rows (the first-touch column)."),
        "  The swarm starts within `random max-pxcor` of the centre and the object",
        "  lies near it, so the first touch comes before any robot reaches an edge.",
        f"- **Convergence.** The medians move by {min(moves):g}-{max(moves):g} ticks "
        f"(firefly sync {vs('firefly', 'sync', 'it_median')},",
        f"  ant sync {vs('ant', 'sync', 'it_median')}; ant netlogo "
        f"{vs('ant', 'netlogo', 'it_median')}), the means",
        f"  (ant sync {vs('ant', 'sync', 'it_mean')}, ant netlogo "
        f"{vs('ant', 'netlogo', 'it_mean')}, firefly",
        f"  netlogo {vs('firefly', 'netlogo', 'it_mean')}); wrap on first in each pair.",
        "  " + ("Every run converged either way." if all_conv else
                "Not every run converged (the converged column)."),
        "- **Delivery: " + ("every run delivered either way.**" if all_home else
                            "not every run delivered** (the delivered column)."),
        "- The run-to-run sd of convergence is "
        f"{sd('firefly')} ticks (firefly) and {sd('ant')} (ant) over the rows, so a",
        "  median's standard error (1.25 sd / sqrt(runs)) is "
        f"{sd('firefly', True)} ticks (firefly) and {sd('ant', True)} (ant):",
        "  a difference of medians below about twice that is within the seed-to-seed spread.",
    ]


def _range(lo: float | None, hi: float | None) -> str:
    return _n(lo) if lo == hi else f"{_n(lo)}-{_n(hi)}"


def _sizes(data: dict) -> list[str]:
    pts = data["points"]
    out = ["| agents (arena) | crowd = yield (default): delivered | delivery: median tick "
           "(least-most) | convergence: tick (least-most) | mean IoU | crowd = block: delivered | "
           "delivery: median tick |", "|---|---|---|---|---|---|---|"]
    for p in (q for q in pts if q["run"] == "Sizes"):
        side = 2 * int(float(p["worldSize"])) + 1
        b = _find(pts, "Sizes-block", agents=p["agents"], worldSize=p["worldSize"])
        out.append(f"| {int(float(p['agents'])):,} ({side} x {side}) | {p['delivered']}/{p['n']} | "
                   f"{_m(p['home_median'])} ({_range(p['home_min'], p['home_max'])}) | "
                   f"{_range(p['it_min'], p['it_max'])} | {_m(p['iou_mean'])} | "
                   f"{b['delivered']}/{b['n']}"
                   + (f" ({b['n'] - b['delivered']} not delivered; "
                      + (f"{b['stalled']} of them not converged)" if b["stalled"] else
                         "all converged)") if b["n"] > b["delivered"] else "")
                   + f" | {_m(b['home_median'])} |")
    runs = data["meta"]["runs"]
    wall = " and ".join(f"{runs[r].get('wall_s', '-')} s (`{runs[r]['command']}`)"
                        for r in SIZE_RUNS)
    out += ["", f"Wall time: {wall}, each with `--engine soa --executor inline --no-plots` "
            "on the loaded 2-core machine."]
    return out


def _wall(meta: dict) -> str:
    """A preset run's wall-time line."""
    return (f"Wall time: {meta.get('wall_s', '-')} s (`{meta['command']}` with `--engine soa "
            f"--executor inline --no-plots`, {meta['points']} points x {meta['seeds']} seeds, "
            "the soa engine's compile cached, on the loaded 2-core machine).")


def _and(items: list[str]) -> str:
    return " and ".join(items) if len(items) < 3 else ", ".join(items[:-1]) + " and " + items[-1]


def _field(data: dict) -> list[str]:
    pts = [p for p in data["points"] if p["run"] == "Field"]
    fields = ("static", "dynamic")
    out = ["| agents, crowd | " + " | ".join(f"{f}: delivered | {f}: delivery median tick "
                                             f"(least-most) | {f}: mean IoU" for f in fields)
           + " |", "|---|" + "---|" * 3 * len(fields)]
    rows = list(dict.fromkeys((p["agents"], p["crowd"]) for p in pts))
    pair = {}
    for a, c in rows:
        st, dy = pair[a, c] = [_find(pts, "Field", agents=a, crowd=c, field=f) for f in fields]
        out.append(f"| {int(float(a))}, {c} | " + " | ".join(
            f"{p['delivered']}/{p['n']} | {_m(p['home_median'])} "
            f"({_range(p['home_min'], p['home_max'])}) | {_m(p['iou_mean'])}" for p in (st, dy))
                   + " |")
    as_many = all(st["delivered"] >= dy["delivered"] for st, dy in pair.values())
    higher = [f"{int(float(a))} robots with `{c}` ({_m(dy['iou_mean'])} against "
              f"{_m(st['iou_mean'])})" for (a, c), (st, dy) in pair.items()
              if (dy["iou_mean"] or 0) > (st["iou_mean"] or 0) + 0.02]
    yld = [(int(float(a)), st, dy) for (a, c), (st, dy) in pair.items() if c == "yield"]
    more = max(((dy["home_median"] or 0) / (st["home_median"] or 1) - 1) * 100
               for _, st, dy in yld)
    meta = data["meta"]["runs"]["Field"]
    out += ["", ("The static field delivers at least as many runs as the dynamic one at every "
                 "point." if as_many else "The dynamic field delivers more runs than the static "
                 "one at some point (the delivered columns)."),
            "The dynamic field's mean IoU is higher by more than 0.02 at "
            + (" and at ".join(higher) if higher else "no point") + ".",
            "With `yield` the dynamic field delivers "
            + ("every run" if all(dy["delivered"] == dy["n"] for _, _, dy in yld) else
               "not every run (the delivered columns)")
            + ", its median delivery tick "
            + _and([_m(dy["home_median"]) for _, _, dy in yld])
            + " against the static field's "
            + _and([_m(st["home_median"]) for _, st, _ in yld])
            + " at " + _and([str(a) for a, _, _ in yld]) + " robots ("
            + (f"at most {math.ceil(more)}% more)." if more > 0 else "never more)."),
            "", _wall(meta)]
    return out


def _obstacles(data: dict) -> list[str]:
    pts = [p for p in data["points"] if p["run"] == "Obstacles"]
    out = ["| wall | delivered | delivery: median tick (least-most) | convergence: median tick "
           "| mean IoU |", "|---|---|---|---|---|"]
    home = {}
    for p in pts:
        wall = "off" if p["point"].endswith("=()") else "on"
        home[wall] = p["home_median"]
        out.append(f"| {wall} | {p['delivered']}/{p['n']} | {_m(p['home_median'])} "
                   f"({_range(p['home_min'], p['home_max'])}) | {_m(p['it_median'])} | "
                   f"{_m(p['iou_mean'])} |")
    meta = data["meta"]["runs"]["Obstacles"]
    out += ["", ("Every run delivered, with the wall and without." if
                 all(p["delivered"] == p["n"] for p in pts) else
                 "Not every run delivered (the delivered column)."),
            f"The median delivery tick goes from {_m(home['off'])} without the wall to "
            f"{_m(home['on'])} with it.",
            "", _wall(meta)]
    return out


def render(data: dict, table: str) -> str:
    pts = data["points"]
    lines = {"runs": lambda: _runs(data), "sensitivity": lambda: _sensitivity(pts),
             "graph1": lambda: _graph1(pts), "stalls": lambda: _stalls(pts),
             "graphs234": lambda: _graphs234(pts), "activation": lambda: _activation(pts),
             "options": lambda: _options(pts), "wrap": lambda: _wrap(pts),
             "models": lambda: _models(pts), "sizes": lambda: _sizes(data),
             "field": lambda: _field(data), "obstacles": lambda: _obstacles(data),
             "options-notes": lambda: _options_notes(pts),
             "wrap-notes": lambda: _wrap_notes(pts)}[table]()
    return "\n".join(lines)


def markers(table: str) -> tuple[str, str]:
    return (f"<!-- bench/thesis_tables.py {table}: begin -->",
            f"<!-- bench/thesis_tables.py {table}: end -->")


def put(doc: str, data: dict, path: str) -> str:
    """The doc at `path` with each of its tables between their markers
    replaced by the rendering."""
    for t in (t for t, d in TABLES.items() if d == path):
        begin, end = markers(t)
        if doc.count(begin) != 1 or doc.count(end) != 1:
            raise ValueError(f"{t}: the doc needs exactly one {begin} and one {end}")
        head, rest = doc.split(begin, 1)
        doc = head + begin + "\n" + render(data, t) + "\n" + end + rest.split(end, 1)[1]
    return doc


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("csv", nargs="*", help="NAME=PATH of a run's sweep.csv, NAME one of "
                    + ", ".join(RUNS))
    ap.add_argument("--json", type=Path, help="write the statistics here")
    ap.add_argument("--from-json", type=Path, help="render the tables from such a file")
    ap.add_argument("--wall", action="append", default=[], help="NAME=SECONDS of a run")
    ap.add_argument("--update", action="store_true",
                    help="keep the other runs of the --json file: replace only the runs given")
    ap.add_argument("--docs", action="store_true",
                    help="put each table between its markers in its doc (TABLES)")
    a = ap.parse_args(argv)
    try:
        if a.from_json:
            data = json.loads(a.from_json.read_text())
        else:
            if not a.csv:
                raise ValueError("give NAME=sweep.csv pairs or --from-json FILE")
            wall = dict(w.split("=", 1) for w in a.wall)
            data = {"meta": {"runs": {}}, "points": []}
            if a.update:
                if not a.json:
                    raise ValueError("--update needs --json FILE, the statistics to update")
                data = json.loads(a.json.read_text())
                given = {pair.partition("=")[0] for pair in a.csv}
                data["points"] = [p for p in data["points"] if p["run"] not in given]
            for pair in a.csv:
                name, _, path = pair.partition("=")
                if name not in RUNS:
                    raise ValueError(f"{pair}: the name must be one of {', '.join(RUNS)}")
                with open(path, newline="") as f:
                    rows = list(csv.DictReader(f))
                pts = reduce(name, rows)
                data["meta"]["runs"][name] = {
                    "command": RUNS[name][0], "points": len(pts),
                    "seeds": len({r["seed"] for r in rows}),
                    **({"wall_s": int(float(wall[name]))} if name in wall else {})}
                data["points"] += pts
            if a.json:
                a.json.write_text(json.dumps(data, indent=1) + "\n")
        if a.docs:
            for path in dict.fromkeys(TABLES.values()):
                (ROOT / path).write_text(put((ROOT / path).read_text(), data, path))
        else:
            for t in TABLES:
                print(render(data, t) + "\n")
    except (OSError, ValueError, KeyError) as e:
        print(f"thesis_tables: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
