"""Measures of a run read off its coordinator and world: the engines' summary
and the per-tick observers (observe.py) both take them from here."""

from __future__ import annotations

from typing import Any

from firmware_logic import perception
from perception.evidence import outline
from perception.polygon import polygon_iou as _polygon_iou


def power_held(coordinator: Any) -> float:
    """The holders' power in weight units (coordinators count hundredths)."""
    return coordinator.power / 100


def shape_iou(coordinator: Any, world: Any) -> float:
    """IoU of the perceived outline (the touched segments' hull) with the
    object's true cells, rounded to 6 places as the summary has it. Both are
    taken in the object's own frame, where it stood at the start: the
    segments where they are now shifted back by the host's idea of the
    displacement (moved_x, moved_y), i.e. as the host stored them, the true cells as the world
    placed them (world.start_cells). So the measure does not jump while the
    object moves: the host learns the displacement a tick after the world
    (measured against the moved world, default seed 2 alternated 0.35 /
    0.69 during the carry)."""
    mx, my = getattr(coordinator, "moved_x", 0), getattr(coordinator, "moved_y", 0)
    perceived = outline([(x - mx, y - my) for x, y in coordinator.segments_now()])
    inter, union = perception.iou_counts(perceived, world.start_cells)
    return round(inter / union, 6) if union else 0.0


def polygon_iou(coordinator: Any, world: Any) -> float:
    """IoU with the object's true cells of the cells enclosed by the polygon
    through the holders' rounded positions (the touches' rx, ry, in angle
    order about their centroid: perception/polygon.py), rounded to 6 places.
    The host stores the touches in the object's frame where it stood at the
    start, so they are compared with world.start_cells, as shape_iou's."""
    return _polygon_iou([(t.rx, t.ry) for t in coordinator.touches], world.start_cells)
