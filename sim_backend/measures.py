"""Measures of a run read off its coordinator and world: the engines' summary
and the per-tick observers (observe.py) both take them from here."""

from __future__ import annotations

from typing import Any

from firmware_logic import perception


def power_held(coordinator: Any) -> float:
    """The holders' power in weight units (coordinators count hundredths)."""
    return coordinator.power / 100


def shape_iou(coordinator: Any, true_cells: list[tuple[int, int]],
              perceived: set[tuple[int, int]] | None = None) -> float:
    """IoU of the perceived outline (the touched segments where they are now;
    pass it when already computed) with the object's true cells, rounded to 6
    places as the summary has it."""
    if perceived is None:
        perceived = perception.outline_cells(coordinator.segments_now())
    inter, union = perception.iou_counts(perceived, true_cells)
    return round(inter / union, 6) if union else 0.0
