"""The per-tick trace of a run (`touchswarm run --trace FILE`): one row per
tick, the DataCollector idea; columns documented in docs/outputs.md.

The columns, in order, are `columns(behaviour)`: tick, n_<state> for each
state the behaviour declares, the FIXED ones (the world's measures among them,
power, shape_iou and polygon_iou, only when the behaviour declares them in
spec.MEASURES), then its spec.REPORTERS. The last row's power, shape_iou,
polygon_iou and reporters equal summary.json's.
"""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Any

from sim_backend.observe import OutputFormatError, Snapshot, output_format

SUFFIXES = (".csv", ".parquet")
# measures the world computes each tick; a column only for a behaviour that
# declares the measure (spec.MEASURES), as in summary.json
# column -> the Snapshot attribute holding it
OFFERED = {"power": "power", "shape_iou": "iou", "polygon_iou": "polygon_iou"}
FIXED = (("tick", "tick, 1..ticks"),
         ("power", "holders' power in weight units (summary.json power)"),
         ("shape_iou", "IoU of the perceived shape with the true one (summary.json shape_iou)"),
         ("polygon_iou", "IoU with the true shape of the cells the polygon through the holders' "
                         "rounded positions encloses (summary.json polygon_iou)"),
         ("touches", "touches the host has accepted so far"),
         ("msgs_up", "messages the host received in this tick"),
         ("msgs_down", "messages the host sent in this tick"),
         ("bad_frames", "frames the link refused in this tick"))


def trace_format(path: Path) -> str:
    """"csv" or "parquet" from the suffix; parquet needs pyarrow."""
    fmt = output_format(path, SUFFIXES, "trace")
    if fmt == "parquet":
        try:
            import pyarrow  # noqa: F401
        except ImportError:
            raise OutputFormatError(f"{path}: .parquet needs pyarrow, which is not installed; "
                                    "use .csv or pip install 'touchswarm[parquet]'") from None
    return fmt


def columns(behaviour: Any) -> list[tuple[str, str]]:
    """(name, meaning) of every column, in order, for a behaviour."""
    fixed = dict(FIXED)
    declared = {name for name, _ in behaviour.spec.MEASURES}
    states = [(f"n_{s}", f"robots in state {s}") for s in behaviour.spec.STATES]
    return ([("tick", fixed["tick"])] + states
            + [(k, v) for k, v in FIXED if k != "tick" and (k not in OFFERED or k in declared)]
            + list(behaviour.reporters))


class Trace:
    """Collects one row per tick from an engine's snapshots."""

    def __init__(self, engine: Any) -> None:
        self.names = [name for name, _ in columns(engine.behaviour)]
        self.offered = [OFFERED[k] for k in OFFERED if k in self.names]   # attributes
        # the engine's instruments add their columns last (docs/outputs.md)
        self.instruments = list(getattr(engine, "instruments", ()))
        self.names += [name for inst in self.instruments for name, _ in inst.COLUMNS]
        self.rows: list[list[Any]] = []
        engine.observe(self.add)

    def add(self, s: Snapshot) -> None:
        counts = s.counts()
        self.rows.append([s.tick, *counts.values(), *(getattr(s, a) for a in self.offered),
                          len(s.touches),
                          s.msgs_up, s.msgs_down, s.bad_frames, *s.reporters.values(),
                          *(v for inst in self.instruments for v in inst.row())])

    def write(self, path: Path) -> Path:
        if trace_format(path) == "parquet":
            import pyarrow as pa
            import pyarrow.parquet as pq
            table = pa.table({n: [r[i] for r in self.rows] for i, n in enumerate(self.names)})
            pq.write_table(table, path)
            return path
        with Path(path).open("w", newline="") as f:
            wr = csv.writer(f, lineterminator="\n")
            wr.writerow(self.names)
            wr.writerows(self.rows)
        return path
