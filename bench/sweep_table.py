"""A markdown table of a sweep.csv, one line per grid point: runs, stalled
(not converged), delivered, and convergence in go iterations (ticks) and
in robot moves (median and mean over the converged runs). The tables of
docs/thesis-reproduction.md and docs/tick-semantics.md come from it.

    .venv/bin/python bench/sweep_table.py sweep-out/sweep.csv [--by KEY,KEY...]

--by: the columns that make a line (default: the grid point label).
"""

import argparse
import csv
import statistics
import sys
from collections import defaultdict
from pathlib import Path


def _f(v):
    return None if v in (None, "") else float(v)


def table(rows: list[dict], by: list[str]) -> list[str]:
    groups: dict[tuple, list[dict]] = defaultdict(list)
    for r in rows:
        groups[tuple(r[k] for k in by)].append(r)
    out = ["| " + " | ".join(by) + " | runs | stalled | delivered | go iterations: median "
           "(mean) | robot moves: median (mean) |",
           "|" + "---|" * (len(by) + 5)]
    for key, rs in groups.items():
        conv = [r for r in rs if _f(r["converged_tick"]) is not None]
        it = [_f(r["converged_tick"]) for r in conv]
        mv = [_f(r["converged_moves"]) for r in conv]
        deliv = sum(1 for r in rs if r["delivered"] in ("True", "true", "1"))

        def fmt(v):
            return f"{statistics.median(v):.0f} ({statistics.mean(v):.0f})" if v else "-"
        out.append("| " + " | ".join(key) + f" | {len(rs)} | {len(rs) - len(conv)} | {deliv} | "
                   f"{fmt(it)} | {fmt(mv)} |")
    return out


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("csv", type=Path)
    ap.add_argument("--by", default="point")
    a = ap.parse_args()
    if not a.csv.is_file():
        print(f"sweep_table: error: {a.csv}: no such file", file=sys.stderr)
        return 2
    with a.csv.open(newline="") as f:
        rows = list(csv.DictReader(f))
    by = [k.strip() for k in a.by.split(",") if k.strip()]
    missing = [k for k in by if rows and k not in rows[0]]
    if missing:
        print(f"sweep_table: error: --by {missing[0]}: not a column of {a.csv}", file=sys.stderr)
        return 2
    print("\n".join(table(rows, by)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
