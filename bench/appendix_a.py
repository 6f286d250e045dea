"""An independent reading of Appendix A's NetLogo model, written from the
appendix alone (none of the project's kernel or FSM): floats, NetLogo's
wrapping world -18..18, `ask robots` in a random order every go iteration,
the search until `power >= objectWeight` (the iteration is the thesis's
convergence). Compared with `--scenario netlogo` (the soa engine) at
fieldDefiance 0, 1, 4, both movement models: stalls and Mann-Whitney U on
the go iterations to convergence, whether the appendix model's stall
count lies in the binomial 95% range of the project's, and Fisher's exact
test of the two stall counts (the range is drawn round the project's
own noisy count, so two identical models fail it at one of the two
stalling points about one time in four). Prints JSON; with
--markdown also the table docs/thesis-reproduction.md carries (between its
markers; a test runs this script in a tiny mode and checks its rows).

    .venv/bin/python bench/appendix_a.py [--seeds 50] [--defiance 0,1,4]
        [--engine soa|reference|auto] [--max-ticks 5000] [--markdown]

Readings the appendix leaves open, each NetLogo 3's: `uphill field` reports
the heading `towards` the greatest neighbour (ties at random), and the
robot keeps its heading when no neighbour is greater than its own patch;
`patch-at-heading-and-distance heading 1` is the patch holding the point
one ahead; headings are floats; `round` rounds halves up.
"""

import argparse
import json
import math
import os
import random
import statistics
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

E = 18                      # screen-edge: patches -18..18 (3.7, "18 x 18")
N = 2 * E + 1
WHITE, YELLOW, BLUE = 0, 1, 2


def wrapc(v):               # a continuous coordinate on the torus
    return (v + E + 0.5) % N - E - 0.5


def pcor(v):                # the patch holding a coordinate
    return int(math.floor(wrapc(v) + 0.5))


def wrapp(p):
    return (p + E) % N - E


class Model:
    def __init__(self, seed, model, defiance, span=45, radius=5, weight=5.0, power=1.0, agents=20):
        self.r = random.Random(seed)
        self.firefly = model == "firefly"
        self.fd = defiance
        self.span, self.radius, self.weight, self.rpower = span, radius, weight, power
        self.color = {}
        self.field = {}
        ox, oy = self.r.randrange(10), self.r.randrange(10)     # CreateWorld
        for a in range(1, 9):                                   # DrawObject, object 1
            self.color[(wrapp(ox + a), wrapp(oy))] = YELLOW
            self.color[(wrapp(ox + a), wrapp(oy + 1))] = YELLOW
        self.bots = []
        for _ in range(agents):                                 # CreateSwarm
            h = self.r.random() * 360
            d = self.r.randrange(E)                             # fd random max-pxcor
            self.bots.append({"x": wrapc(d * math.sin(math.radians(h))),
                              "y": wrapc(d * math.cos(math.radians(h))), "h": h,
                              "obj": False, "fld": False, "mob": True})
        self.occ = {}                                           # turtles-on: robots a patch holds
        for b in self.bots:
            b["p"] = self.here(b)
            self.occ[b["p"]] = self.occ.get(b["p"], 0) + 1
        self.found = False
        self.loc = (0.0, 0.0)
        self.power = 0.0

    def ahead(self, b):
        return (pcor(b["x"] + math.sin(math.radians(b["h"]))),
                pcor(b["y"] + math.cos(math.radians(b["h"]))))

    def here(self, b):
        return (pcor(b["x"]), pcor(b["y"]))

    def head_carefully(self, b):
        p = self.ahead(b)
        if self.occ.get(p, 0) > 0 or self.color.get(p, WHITE) != WHITE:   # the caller counts too
            b["h"] = self.r.randrange(360)
        else:
            step = 1.0 if self.firefly else 0.25
            b["x"] = wrapc(b["x"] + step * math.sin(math.radians(b["h"])))
            b["y"] = wrapc(b["y"] + step * math.cos(math.radians(b["h"])))
            self.occ[b["p"]] -= 1
            b["p"] = self.here(b)
            self.occ[b["p"]] = self.occ.get(b["p"], 0) + 1

    def random_head(self, b):
        if self.firefly:
            b["h"] = self.r.randrange(360)
        self.head_carefully(b)

    def look(self, b):
        p = self.ahead(b)
        if self.color.get(p, WHITE) == YELLOW:
            self.color[p] = BLUE
            b["obj"], b["mob"] = True, False
            self.loc = (b["x"], b["y"])
            self.found = True
            self.power += self.rpower

    def find_object(self, b):
        if self.firefly:
            for h in (0, 90, 180, 270):
                if not b["obj"]:
                    b["h"] = h
                    self.look(b)
                if not b["obj"]:
                    b["h"] = self.r.randrange(360)
        else:
            turn = self.r.randrange(self.span) if self.span > 0 else 0
            b["h"] = (b["h"] + (turn if self.r.randrange(100) % 2 == 0 else -turn)) % 360
            self.look(b)

    def follow_field(self, b):
        px, py = self.here(b)
        best, win = self.field.get((px, py), 0), []
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                if dx or dy:
                    v = self.field.get((wrapp(px + dx), wrapp(py + dy)), 0)
                    if v > best:
                        best, win = v, [(dx, dy)]
                    elif v == best and win:
                        win.append((dx, dy))
        if win:
            dx, dy = win[self.r.randrange(len(win))]
            b["h"] = math.degrees(math.atan2(px + dx - b["x"], py + dy - b["y"])) % 360
        self.head_carefully(b)

    def signal(self, tx, ty):
        cx, cy = pcor(tx), pcor(ty)
        r = self.radius
        for dx in range(-r, r + 1):
            for dy in range(-r, r + 1):
                if dx * dx + dy * dy <= r * r:
                    p = (wrapp(cx + dx), wrapp(cy + dy))
                    ddx, ddy = cx + dx - tx, cy + dy - ty
                    d = math.hypot(ddx, ddy)
                    self.field[p] = self.field.get(p, 0) + math.floor(10 / (1 + d) + 0.5)

    def go(self):
        order = self.bots[:]
        self.r.shuffle(order)
        for b in order:
            if b["mob"] and not b["obj"] and not b["fld"]:
                self.random_head(b)
                self.find_object(b)
                if not b["obj"]:
                    p = self.ahead(b)
                    if self.field.get(p, 0) > 0:                # FindField
                        b["fld"] = True
                        self.follow_field(b)
            if b["fld"] and not b["obj"]:
                self.follow_field(b)
                for _ in range(self.fd):
                    self.random_head(b)
                self.find_object(b)
                if b["obj"]:
                    continue
            if not b["fld"] and b["obj"]:
                self.field[self.here(b)] = 10
        if self.found:
            self.signal(*self.loc)
            self.found = False

    def run(self, max_iter=5000):
        for it in range(1, max_iter + 1):
            self.go()
            if self.power >= self.weight:
                return it
        return None


def mann_whitney(a, b):
    """Two-sided Mann-Whitney U with the normal approximation (tie-corrected)."""
    try:
        from scipy.stats import mannwhitneyu
        return float(mannwhitneyu(a, b, alternative="two-sided").pvalue)
    except ImportError:
        pass
    allv = sorted((v, i) for i, v in enumerate(a + b))
    ranks = [0.0] * len(allv)
    i, ties = 0, 0.0
    while i < len(allv):
        j = i
        while j + 1 < len(allv) and allv[j + 1][0] == allv[i][0]:
            j += 1
        for k in range(i, j + 1):
            ranks[allv[k][1]] = (i + j) / 2 + 1
        t = j - i + 1
        ties += t ** 3 - t
        i = j + 1
    n1, n2 = len(a), len(b)
    u = sum(ranks[:n1]) - n1 * (n1 + 1) / 2
    n = n1 + n2
    sd = math.sqrt(n1 * n2 / 12 * ((n + 1) - ties / (n * (n - 1))))
    z = (abs(u - n1 * n2 / 2) - 0.5) / sd if sd else 0.0
    return math.erfc(z / math.sqrt(2))


def binomial_range(k, n, level=0.95):
    """The central `level` range of Binomial(n, k / n): the stall counts a
    model with the project's stall rate gives in n runs."""
    p = k / n
    cdf, lo, hi = 0.0, None, n
    for i in range(n + 1):
        cdf += math.comb(n, i) * p ** i * (1 - p) ** (n - i)
        if lo is None and cdf >= (1 - level) / 2:
            lo = i
        if cdf >= 1 - (1 - level) / 2 - 1e-12:
            hi = i
            break
    return lo, hi


def fisher_exact(a, n1, b, n2):
    """Two-sided Fisher's exact test of a stalled of n1 against b of n2: the
    chance, with the margins fixed, of a table no likelier than this one."""
    k = a + b

    def pr(x):
        return math.comb(n1, x) * math.comb(n2, k - x) / math.comb(n1 + n2, k)
    p0 = pr(a)
    return min(1.0, sum(pr(x) for x in range(max(0, k - n2), min(k, n1) + 1)
                        if pr(x) <= p0 * (1 + 1e-9)))


def project(model, defiance, seeds, engine="auto", max_ticks=5000):
    from sim_backend import scenario, sweep
    from sim_backend.sweep import Point
    pt = Point("a", (("movementModel", model), ("fieldDefiance", defiance)))
    rows = sweep.sweep([pt], seeds, base=scenario.load("netlogo"), until="converged",
                       overrides={"maxTicks": max_ticks}, engine=engine)
    return [r["converged_tick"] for r in rows]


def markdown(out):
    """The agreement table: per model and fieldDefiance, both models' median
    go iterations (stalled/runs), the Mann-Whitney p and the stall check."""
    lines = ["| model | fD | appendix model: median (stalled/runs) | `--scenario netlogo`: "
             "median (stalled/runs) | Mann-Whitney p | project's binomial 95% stall range: "
             "appendix inside | stalls: Fisher p |", "|---|---|---|---|---|---|---|"]
    for c in out:
        def med(v):
            return "-" if v is None else f"{v:g}"
        lo, hi = c["project_stall_range"]
        lines.append(f"| {c['movementModel']} | {c['fieldDefiance']} | "
                     f"{med(c['appendix_median'])} ({c['appendix_stalled']}/{c['n']}) | "
                     f"{med(c['project_median'])} ({c['project_stalled']}/{c['n']}) | "
                     f"{med(c['mann_whitney_p'])} | {lo}-{hi}: "
                     f"{'yes' if lo <= c['appendix_stalled'] <= hi else 'no'} | "
                     f"{c['fisher_p']:g} |")
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=50)
    ap.add_argument("--defiance", default="0,1,4")
    ap.add_argument("--engine", choices=("auto", "soa", "reference"), default="auto",
                    help="the project's engine (bit-identical; soa is the fast one)")
    ap.add_argument("--max-ticks", type=int, default=5000)
    ap.add_argument("--markdown", action="store_true")
    a = ap.parse_args(argv)
    seeds = list(range(1, a.seeds + 1))
    out = []
    for model in ("firefly", "ant"):
        for fd in (int(v) for v in a.defiance.split(",")):
            ours = [Model(s, model, fd).run(a.max_ticks) for s in seeds]
            proj = project(model, fd, seeds, a.engine, a.max_ticks)
            x = [v for v in ours if v is not None]
            y = [v for v in proj if v is not None]
            out.append({"movementModel": model, "fieldDefiance": fd, "n": len(seeds),
                        "appendix_stalled": len(ours) - len(x),
                        "project_stalled": len(proj) - len(y),
                        "project_stall_range": binomial_range(len(proj) - len(y), len(seeds)),
                        "appendix_median": statistics.median(x) if x else None,
                        "project_median": statistics.median(y) if y else None,
                        "mann_whitney_p": round(mann_whitney(x, y), 3) if x and y else None,
                        "fisher_p": round(fisher_exact(len(ours) - len(x), len(ours),
                                                       len(proj) - len(y), len(proj)), 3)})
            print(json.dumps(out[-1]), file=sys.stderr)
    print(json.dumps(out, indent=1))
    if a.markdown:
        print(markdown(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
