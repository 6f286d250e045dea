"""Each claim of the thesis's chapter 5 beside our figure and a verdict.

Reads the sweep.csv of the thesis study under every Appendix A rule,

    touchswarm sweep --thesis --scenario netlogo --engine soa --out DIR

reduces it to per-point statistics (runs, stalls, and the mean with its
standard error and the median of convergence in go iterations,
`converged_tick`, and in robot moves, `converged_moves`, over the converged
runs; for Figures 22-24 the mean `polygon_iou` and `shape_iou`), judges
every claim on them and prints the markdown table docs/thesis-reproduction.md
carries, then the statistics and the claims as JSON (--json FILE writes the
JSON there instead; --from-json FILE renders the table from such a file).

    .venv/bin/python bench/thesis_claims.py DIR/sweep.csv [--json FILE]
    .venv/bin/python bench/thesis_claims.py --from-json bench/thesis_claims.json \
        [--docs docs/thesis-reproduction.md]

--docs FILE puts the table between the markers of FILE (a test checks
docs/thesis-reproduction.md's table is what --from-json renders).

Verdicts: a trend "rises" ("falls") when the mean at the last level of the
factor is above (below) the mean at the first by more than 1.96 standard
errors of the difference, else "flat"; it is "steady" when, besides, no
step between neighbouring levels goes the other way by that much. A claim
about time holds when it holds in go iterations and in robot moves, does
not hold when it holds in neither, and depends on the time unit otherwise
(the thesis timed wall-clock milliseconds, docs/thesis-reproduction.md
"Units"). fieldDefiance 0 stalls (as the thesis's 3.9.2 predicts), so
Graph 1's trends are judged over fieldDefiance 1-10.
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

# the study behind each experiment's rows and the command that runs it
COMMANDS = {"thesis": "touchswarm sweep --thesis --scenario netlogo --engine soa --out DIR",
            "scalability": "touchswarm sweep --study scalability --scenario netlogo "
                           "--engine soa --out DIR2"}
COMMAND = COMMANDS["thesis"]
SELF = ("bench/thesis_claims.py DIR/sweep.csv DIR2/sweep.csv "
        "--json bench/thesis_claims.json")
MODELS = ("firefly", "ant")
# experiment -> the column its x is read from
X = {"graph1": "fieldDefiance", "graph2": "sigRadius", "graph3": "rPower",
     "scalability": "agents", "shapes": "required"}
UNITS = (("it", "go iterations"), ("mv", "robot moves"))
OBJECTS = ("bar", "L", "cross", "X")
Z = 1.96
BEGIN = "<!-- bench/thesis_claims.py: begin -->"
END = "<!-- bench/thesis_claims.py: end -->"


def _f(v):
    return None if v in (None, "") else float(v)


def _mean_sem(vals: list[float]) -> tuple[float | None, float | None]:
    if not vals:
        return None, None
    m = statistics.fmean(vals)
    sem = statistics.stdev(vals) / math.sqrt(len(vals)) if len(vals) > 1 else 0.0
    return round(m, 3), round(sem, 3)


def point_stats(rows: list[dict]) -> list[dict]:
    """One entry per (experiment, series, x): the statistics every claim is
    judged on, in the sweep's order."""
    groups: dict[tuple, list[dict]] = defaultdict(list)
    for r in rows:
        exp = r["experiment"]
        if exp not in X:
            continue
        series = r["object"] if exp == "shapes" else r["movementModel"]
        groups[(exp, series, float(r[X[exp]]))].append(r)
    out = []
    for (exp, series, x), rs in groups.items():
        conv = [r for r in rs if _f(r["converged_tick"]) is not None]
        e = {"experiment": exp, "series": series, "x": x, "n": len(rs),
             "stalled": len(rs) - len(conv), "required": int(float(rs[0]["required"]))}
        for key, col in (("it", "converged_tick"), ("mv", "converged_moves")):
            vals = [_f(r[col]) for r in conv]
            e[f"{key}_mean"], e[f"{key}_sem"] = _mean_sem(vals)
            e[f"{key}_median"] = statistics.median(vals) if vals else None
        if exp == "shapes":
            for key, col in (("poly", "polygon_iou"), ("hull", "shape_iou")):
                e[f"{key}_mean"], e[f"{key}_sem"] = _mean_sem(
                    [_f(r[col]) for r in rs if _f(r[col]) is not None])
        out.append(e)
    return out


def _series(points: list[dict], exp: str, series: str) -> list[dict]:
    return sorted((p for p in points if p["experiment"] == exp and p["series"] == series),
                  key=lambda p: p["x"])


def _diff(a: dict, b: dict, key: str) -> float:
    """b - a in standard errors of the difference (0 when both are exact)."""
    d = b[f"{key}_mean"] - a[f"{key}_mean"]
    se = math.hypot(a[f"{key}_sem"], b[f"{key}_sem"])
    return d / se if se else (math.copysign(math.inf, d) if d else 0.0)


def trend(pts: list[dict], key: str) -> str:
    """rises, falls or flat from the first level to the last; "steadily"
    added when no neighbouring step goes the other way significantly."""
    pts = [p for p in pts if p[f"{key}_mean"] is not None]
    if len(pts) < 2:
        return "no data"
    z = _diff(pts[0], pts[-1], key)
    word = "rises" if z > Z else "falls" if z < -Z else "flat"
    if word == "flat":
        return word
    sign = 1 if word == "rises" else -1
    back = [_diff(a, b, key) * sign < -Z for a, b in zip(pts, pts[1:])]
    word += " steadily" if not any(back) else " unsteadily"
    mid = pts[len(pts) // 2]
    if _diff(mid, pts[-1], key) * sign <= Z:
        word += f", level from {_fmt(mid['x'])}"
    return word


def _fmt(v: float | None) -> str:
    if v is None:
        return "-"
    return f"{v:.0f}" if abs(v) >= 10 else f"{v:.2f}".rstrip("0").rstrip(".")


def _curve(pts: list[dict], key: str) -> str:
    return " / ".join(_fmt(p[f"{key}_mean"]) for p in pts)


def _xs(pts: list[dict]) -> str:
    return " / ".join(_fmt(p["x"]) for p in pts)


def _verdict(per_unit: list[bool]) -> str:
    if all(per_unit):
        return "holds"
    if not any(per_unit):
        return "does not hold"
    return "depends on the time unit"


def _time_claim(claim: str, source: str, points: list[dict], exp: str, models: tuple,
                want: str, lo: float | None = None, x_name: str = "") -> dict:
    """A claim that `exp`'s convergence time `want`s (rises, falls, rises
    steadily) over its factor for each of `models`, in both units."""
    figure, ok = [], []
    for key, unit in UNITS:
        good = True
        for m in models:
            pts = [p for p in _series(points, exp, m) if lo is None or p["x"] >= lo]
            t = trend(pts, key)
            figure.append(f"{m}, {unit}: {_curve(pts, key)} ({t})")
            good = good and t.startswith(want)
        ok.append(good)
    x = _xs([p for p in _series(points, exp, models[0]) if lo is None or p["x"] >= lo])
    return {"claim": claim, "source": source, "levels": f"{x_name or X[exp]} {x}",
            "figure": "; ".join(figure), "verdict": _verdict(ok)}


def claims(points: list[dict]) -> list[dict]:
    out = [
        _time_claim("Graph 1a: firefly's convergence time rises (irregularly) with "
                    "fieldDefiance", "5.2.1", points, "graph1", ("firefly",), "rises", lo=1),
        _time_claim("Graph 1b: ant's convergence time rises steadily with fieldDefiance",
                    "5.2.1", points, "graph1", ("ant",), "rises steadily", lo=1),
        _time_claim("Graph 2: a larger signal radius reduces convergence time", "5.2.2",
                    points, "graph2", MODELS, "falls"),
        _time_claim("Graph 3: powerful robots converge quicker than weak ones", "5.2.3, 5.4",
                    points, "graph3", MODELS, "falls"),
    ]
    # Graph 4: the same runs against robots required (ceil(weight / power))
    # (rPower 1.25 and 1.5 both need 4 robots: the same runs, drawn once)
    g4 = list({(p["series"], p["required"]): dict(p, experiment="graph4", x=float(p["required"]))
               for p in points if p["experiment"] == "graph3"}.values())
    out.append(_time_claim("Graph 4: more robots required (of a population of 20) take "
                           "longer, the inverse of Graph 3", "5.2.4", g4, "graph4", MODELS,
                           "rises", x_name="robots required"))
    # rPower 1.25, ant: "unreasonably long"
    ant = {p["x"]: p for p in _series(points, "graph3", "ant")}
    if {1.0, 1.25, 1.5} <= set(ant):
        ok = []
        fig = []
        for key, unit in UNITS:
            z_lo, z_hi = _diff(ant[1.0], ant[1.25], key), _diff(ant[1.5], ant[1.25], key)
            ok.append(z_lo > Z and z_hi > Z)
            fig.append(f"{unit}: rPower 1 / 1.25 / 1.5: {_fmt(ant[1.0][key + '_mean'])} / "
                       f"{_fmt(ant[1.25][key + '_mean'])} / {_fmt(ant[1.5][key + '_mean'])}")
        fig.append(f"stalled {ant[1.0]['stalled']} / {ant[1.25]['stalled']} / "
                   f"{ant[1.5]['stalled']} of {ant[1.25]['n']}")
        out.append({"claim": "rPower 1.25 (ant) took unreasonably long to converge",
                    "source": "5.2.3", "levels": "rPower 1, 1.25, 1.5",
                    "figure": "; ".join(fig), "verdict": _verdict(ok)})
    # firefly quicker than ant, at every point of Graphs 1-3
    ok, fig = [], []
    for key, unit in UNITS:
        n = quicker = slower = 0
        for exp in ("graph1", "graph2", "graph3"):
            ff = {p["x"]: p for p in _series(points, exp, "firefly")}
            for p in _series(points, exp, "ant"):
                f = ff.get(p["x"])
                if f is None or f[f"{key}_mean"] is None or p[f"{key}_mean"] is None:
                    continue
                n += 1
                z = _diff(f, p, key)
                quicker += z > Z
                slower += z < -Z
        ok.append(n > 0 and slower == 0 and quicker >= n / 2)
        fig.append(f"{unit}: firefly quicker at {quicker} of {n} points, slower at {slower}")
    out.append({"claim": "firefly robots converge quicker than ant robots (Graphs 1-4)",
                "source": "5.2.3, 5.4", "levels": "every point of Graphs 1-3",
                "figure": "; ".join(fig), "verdict": _verdict(ok)})
    # more robots, quicker (5.1)
    if any(p["experiment"] == "scalability" for p in points):
        out.append(_time_claim("more robots converge quicker (scalability)", "5.1", points,
                               "scalability", MODELS, "falls"))
    # fieldDefiance 0 stalls (the thesis's own prediction)
    f0 = [p for p in points if p["experiment"] == "graph1" and p["x"] == 0]
    if f0:
        one = {p["series"]: p["stalled"] for p in points
               if p["experiment"] == "graph1" and p["x"] == 1}
        fig = "; ".join(f"{p['series']}: {p['stalled']} of {p['n']} stalled (fD 1: "
                        f"{one.get(p['series'], '-')})" for p in f0)
        out.append({"claim": "robots that only follow the field stop at its peak "
                             "(fieldDefiance 0: runs stall, none at 1)", "source": "3.9.2",
                    "levels": "fieldDefiance 0", "figure": fig,
                    "verdict": "holds" if all(p["stalled"] > 0 and not one.get(p["series"])
                                              for p in f0) else "does not hold"})
    # Figures 22-24: more robots, a better shape (the holder polygon)
    fig, ok = [], []
    hull = []
    for obj in OBJECTS:
        pts = _series(points, "shapes", obj)
        if not pts:
            continue
        t = trend(pts, "poly")
        ok.append(t.startswith("rises"))
        fig.append(f"{obj} {_curve(pts, 'poly')} ({t})")
        hull.append(f"{obj} {_curve(pts, 'hull')} ({trend(pts, 'hull')})")
    if fig:
        ns = _xs(_series(points, "shapes", OBJECTS[0]))
        out.append({"claim": "Figures 22-24: the more robots, the better the extracted shape",
                    "source": "5.3, 5.4", "levels": f"holders {ns}",
                    "figure": "polygon_iou: " + "; ".join(fig) + ". shape_iou (ours): "
                              + "; ".join(hull),
                    "verdict": "holds" if all(ok) else "holds for " + ", ".join(
                        o for o, k in zip(OBJECTS, ok) if k) if any(ok) else
                    "does not hold"})
    return out


def markdown(cl: list[dict], meta: dict) -> str:
    runs = " and ".join(f"`{m['command']}` ({m['seeds']} seeds a point, maxTicks "
                        f"{m['maxTicks']})" for m in meta["runs"])
    lines = [f"Made by {runs}, seeds 1..N, until converged, then `.venv/bin/python {SELF}`; "
             "means over the converged runs, a trend judged "
             "from the first level to the last (z > 1.96; 'level from x': no significant "
             "change from the middle level x on).",
             "",
             "| thesis's claim | section | levels | our figure (mean) | verdict |",
             "|---|---|---|---|---|"]
    for c in cl:
        lines.append(f"| {c['claim']} | {c['source']} | {c['levels']} | {c['figure']} | "
                     f"**{c['verdict']}** |")
    return "\n".join(lines)


def meta_of(rows: list[dict]) -> dict:
    """Per study in the rows: its command, seeds a point and maxTicks."""
    runs = []
    for study, command in COMMANDS.items():
        rs = [r for r in rows if (r["experiment"] == "scalability") == (study == "scalability")]
        if rs:
            runs.append({"command": command, "seeds": len({int(r["seed"]) for r in rs}),
                         "maxTicks": max(int(float(r["maxTicks"])) for r in rs)})
    return {"runs": runs}


def render(data: dict) -> str:
    return markdown(claims(data["points"]), data["meta"])


def docs_block(text: str) -> str:
    """The table between the markers in a document's text."""
    return text.split(BEGIN, 1)[1].split(END, 1)[0].strip()


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("csv", type=Path, nargs="*",
                    help="the sweep.csv of the thesis study (and of the scalability study)")
    ap.add_argument("--from-json", type=Path, help="render from a JSON this script wrote")
    ap.add_argument("--json", type=Path, help="write the statistics and claims here")
    ap.add_argument("--docs", type=Path,
                    help="also put the table between the markers of this markdown file "
                         "(docs/thesis-reproduction.md)")
    a = ap.parse_args(argv)
    if bool(a.csv) == (a.from_json is not None):
        print("thesis_claims: error: give sweep.csv files or --from-json FILE", file=sys.stderr)
        return 2
    for src in a.csv or [a.from_json]:
        if not src.is_file():
            print(f"thesis_claims: error: {src}: no such file", file=sys.stderr)
            return 2
    if a.csv:
        rows = []
        for path in a.csv:
            with path.open(newline="") as f:
                got = list(csv.DictReader(f))
            missing = [c for c in ("experiment", "converged_tick", "converged_moves",
                                   "polygon_iou", "shape_iou") if got and c not in got[0]]
            if missing or not got:
                print(f"thesis_claims: error: {path}: no {missing[0] if missing else 'rows'}"
                      f"; expected the sweep.csv of `{COMMAND}`", file=sys.stderr)
                return 2
            rows += got
        data = {"meta": meta_of(rows), "points": point_stats(rows)}
    else:
        data = json.loads(a.from_json.read_text())
    data["claims"] = claims(data["points"])
    table = markdown(data["claims"], data["meta"])
    print(table)
    if a.docs:
        text = a.docs.read_text()
        if text.count(BEGIN) != 1 or text.count(END) != 1:
            print(f"thesis_claims: error: {a.docs}: expected one {BEGIN} and one {END}",
                  file=sys.stderr)
            return 2
        head, rest = text.split(BEGIN, 1)
        a.docs.write_text(f"{head}{BEGIN}\n{table}\n{END}{rest.split(END, 1)[1]}")
    if a.json:
        a.json.write_text(json.dumps(data, indent=1) + "\n")
    else:
        print(json.dumps(data, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
