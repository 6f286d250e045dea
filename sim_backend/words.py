"""How a run's outputs speak of its behaviour: the one place the text
summary, world.png, the GIF, the live view and the sweep plots take their
words from.

Everything derives from the behaviour's spec.py: its MEASURES and
REPORTERS ((name, meaning), ...) by default, one line or panel each, titled
by its meaning. A behaviour may say more with these optional declarations
(the thesis does, docs/writing-a-behaviour.md "Its words"):

    HEADER   the summary's first line, a str.format template of summary keys
    SUMMARY  ((label, template), ...): the summary's lines instead of one per
             measure; `{key!t}` reads a tick ("never" when None), `{key!n}`
             a list's length. A line whose keys the run did not give is left out.
    RESULT   (key, word when true, word when false): the result line's words
    SHAPE    the measure scoring the perceived shape: world.png then has the
             perceived-vs-true panel, the GIF and the live view draw the
             perceived cells
    LOAD     (what is held, what it must reach), e.g. ("power", "weight"):
             the live view's bar and its touch events
    HOME     True when the scenario's home (homeX, homeY) means something to
             the behaviour: the live view draws it and names it in its
             legend; by default True exactly when it declares LOAD (what is
             held is taken home)
    PLOTS    ((measure, label), ...): the sweep plots' panels instead of
             every numeric measure

A behaviour's package may also give `summary_values(coordinator)`: more
named values for its SUMMARY templates (text computed on the host).
"""

from __future__ import annotations

import string
from dataclasses import dataclass
from typing import Any, Sequence

DEFAULT_HEADER = "scenario {scenario}: {robots} robots, behaviour {behaviour}, seed {seed}"
DEFAULT_RESULT = ("delivered", "DONE", "NOT done")


@dataclass(frozen=True)
class Words:
    """What one behaviour's outputs say; `of(behaviour)` builds it."""
    name: str
    measures: tuple[tuple[str, str], ...]     # spec.MEASURES
    reporters: tuple[tuple[str, str], ...]    # spec.REPORTERS
    header: str
    lines: tuple[tuple[str, str], ...]        # (label, template)
    result: tuple[str, str, str]
    shape: str | None
    load: tuple[str, str] | None
    home: bool                                # spec.HOME
    plots: tuple[tuple[str, str], ...]        # (measure, label); empty: every numeric one

    def title(self, name: str) -> str:
        """A measure's or reporter's declared meaning (its name when undeclared)."""
        return dict(self.reporters + self.measures).get(name, name)

    def label(self, name: str) -> str:
        """A measure's short label: its PLOTS label, else its name."""
        return dict(self.plots).get(name, name)

    def shown(self) -> tuple[tuple[str, str], ...]:
        """(name, title) of every measure, then every reporter not also a measure."""
        names = {n for n, _ in self.measures}
        return self.measures + tuple(r for r in self.reporters if r[0] not in names)


def of(behaviour: Any) -> Words:
    """The words of a behaviour (a registry.Behaviour, or its name or folder)."""
    if isinstance(behaviour, str) or not hasattr(behaviour, "spec"):
        from sim_backend import registry
        behaviour = registry.load(behaviour)
    spec = behaviour.spec
    measures = tuple(spec.MEASURES)
    reporters = tuple(getattr(spec, "REPORTERS", ()))
    _pairs(spec.NAME, measures, "MEASURES")
    _pairs(spec.NAME, reporters, "REPORTERS")
    lines = tuple(getattr(spec, "SUMMARY", ())) or tuple(
        (t, "{%s!t}" % n if is_tick(n) else "{%s}" % n) for n, t in measures + tuple(
            r for r in reporters if r[0] not in dict(measures)))
    w = Words(spec.NAME, measures, reporters, getattr(spec, "HEADER", DEFAULT_HEADER),
              lines, tuple(getattr(spec, "RESULT", DEFAULT_RESULT)),
              getattr(spec, "SHAPE", None), getattr(spec, "LOAD", None),
              getattr(spec, "HOME", getattr(spec, "LOAD", None) is not None),
              tuple(getattr(spec, "PLOTS", ())))
    _check(w)
    return w


def _bad(name: str, what: str, why: str) -> Exception:
    from sim_backend.registry import BehaviourError
    return BehaviourError(f"behaviour {name!r}: spec.py {what}: {why}")


def _pairs(name: str, rows: tuple, what: str) -> None:
    for row in rows:
        if not (isinstance(row, tuple) and len(row) == 2
                and all(isinstance(x, str) for x in row)):
            raise _bad(name, what, f"{row!r} is not a (text, text) pair")


def _check(w: Words) -> None:
    """The optional declarations' shapes; BehaviourError naming the first wrong one."""
    def bad(what: str, why: str) -> Exception:
        return _bad(w.name, what, why)

    _pairs(w.name, w.lines, "SUMMARY")
    _pairs(w.name, w.plots, "PLOTS")
    for template in [w.header] + [t for _, t in w.lines]:
        try:
            for _, _, _, conversion in string.Formatter().parse(template):
                if conversion not in (None, "r", "s", "a", "t", "n"):
                    raise ValueError(f"unknown conversion !{conversion}; "
                                     "!t (a tick) or !n (a count)")
        except ValueError as err:
            raise bad("HEADER" if template is w.header else "SUMMARY",
                      f"{template!r}: {err}") from None
    if len(w.result) != 3 or not all(isinstance(x, str) for x in w.result):
        raise bad("RESULT", f"{w.result!r} is not (summary key, word if true, word if false)")
    if not isinstance(w.home, bool):
        raise bad("HOME", f"{w.home!r} is not True or False")
    if w.load is not None and (len(w.load) != 2 or not all(isinstance(x, str) for x in w.load)):
        raise bad("LOAD", f"{w.load!r} is not (held, needed): two coordinator attribute names")
    measures = dict(w.measures)
    for what, names in (("SHAPE", [w.shape] if w.shape is not None else []),
                        ("PLOTS", [n for n, _ in w.plots])):
        for name in names:
            if name not in measures:
                raise bad(what, f"{name!r} is not one of its MEASURES "
                                f"({', '.join(measures)})")


def is_tick(name: str) -> bool:
    """A measure named *_tick is a tick (None: it never happened): the summary
    says "tick N" or "never", the sweep plots censor it at maxTicks."""
    return name.endswith("_tick")


def named_text(name: str, v: Any) -> str:
    """A measure's value as text: a tick as "tick N" or "never" (is_tick)."""
    if is_tick(name):
        return "never" if v is None else f"tick {v}"
    return value_text(v)


def value_text(v: Any) -> str:
    """A value as the summary prints it."""
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:g}"
    if isinstance(v, (list, tuple)):
        return str(len(v))
    return str(v)


class _Formatter(string.Formatter):
    """str.format with `!t` (a tick: "tick N", "never" for None) and `!n`
    (a list's length); a None value prints as "-" whatever its format."""

    def convert_field(self, value: Any, conversion: str | None) -> Any:
        if conversion == "t":
            return "never" if value is None else f"tick {value}"
        if conversion == "n":
            return len(value or ())
        return super().convert_field(value, conversion)

    def format_field(self, value: Any, format_spec: str) -> str:
        if value is None:
            return "-"
        if not format_spec:
            return value_text(value)
        return super().format_field(value, format_spec)


_FORMAT = _Formatter()


def fill(template: str, values: dict) -> str | None:
    """The template filled from values; None when it names a key values lacks."""
    try:
        return _FORMAT.vformat(template, (), values)
    except (KeyError, IndexError):
        return None


def summary_values(behaviour: Any, summary: dict, coordinator: Any = None) -> dict:
    """What the summary's templates read: the run's summary, the reporters'
    final values and the behaviour's own summary_values(coordinator)."""
    values = {"behaviour": behaviour.spec.NAME, **summary}
    if coordinator is not None:
        values.update({k: v for k, v in behaviour.report(coordinator).items()
                       if k not in values})
        hook = getattr(behaviour.package, "summary_values", None)
        if hook is not None:
            values.update(hook(coordinator))
    return values


def summary_lines(behaviour: Any, summary: dict, coordinator: Any = None) -> list[str]:
    """The text summary's header and measure lines (run, mission)."""
    w = of(behaviour)
    values = summary_values(behaviour, summary, coordinator)
    out = [fill(w.header, values) or fill(DEFAULT_HEADER, values) or w.name]
    width = _width(w)
    for label, template in w.lines:
        text = fill(template, values)
        if text is not None:
            out.append(f"  {label:<{width}} {text}".rstrip())
    return out


def _width(w: Words) -> int:
    return max([16] + [len(label) + 1 for label, _ in w.lines])


def result_line(behaviour: Any, summary: dict) -> str:
    """The result line: RESULT's words, the ticks, the outcome when not done."""
    w = of(behaviour)
    key, yes, no = w.result
    done = bool(summary.get(key))
    outcome = summary.get("outcome")
    return (f"  {'result':<{_width(w)}} {yes if done else no} after {summary['ticks']} ticks"
            + ("" if done or not outcome else f" ({outcome})"))


def frame_title(w: Words, tick: int, reporters: dict, iou: float | None = None,
                phase: str | None = None, load: tuple | None = None) -> str:
    """The GIF's frame title: the tick and the host's phase (its status()),
    then on a second line the declared load (e.g. "power 2.00 of weight
    5.00"), each reporter and the shape's score when declared."""
    parts = []
    if w.load is not None and load is not None:
        parts.append(f"{w.load[0]} {load[0]:.2f} of {w.load[1]} {load[1]:.2f}")
    parts += [f"{name} {named_text(name, v)}" for name, v in reporters.items()]
    if w.shape is not None and iou is not None:
        parts.append(f"{w.label(w.shape)} {iou:.2f}")
    head = f"tick {tick}" + (f": {phase}" if phase else "")
    return head + ("\n" + ", ".join(parts) if parts else "")


def shown_values(w: Words, values: dict) -> list[dict]:
    """[{name, title, value}] of every measure and reporter values hold (the view)."""
    return [{"name": n, "title": t, "value": values[n]} for n, t in w.shown() if n in values]


def _numeric(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def plot_kind(name: str, values: Sequence[Any]) -> str | None:
    """How a measure's sweep values are drawn: "tick" (a tick, None = never:
    censored at maxTicks), "rate" (true/false: the fraction true), "value"
    (a number: mean and spread), None (text: not drawn)."""
    seen = [v for v in values if v is not None]
    if is_tick(name):
        return "tick"
    if seen and all(isinstance(v, bool) for v in seen):
        return "rate"
    if seen and all(_numeric(v) for v in seen):
        return "value"
    return None


def plot_panels(behaviours: Sequence[Any], columns: dict[str, list]) -> list[tuple[str, str, str]]:
    """(measure, label, kind) of every sweep-plot panel for rows of these
    behaviours: each behaviour's PLOTS, or else every measure whose values
    (`columns`: name -> values read from the rows) are numbers or true/false."""
    out: dict[str, tuple[str, str, str]] = {}
    for b in behaviours:
        w = of(b)
        chosen = w.plots or tuple((n, t) for n, t in w.measures)
        for name, label in chosen:
            if name in out or name not in columns:
                continue
            kind = plot_kind(name, columns[name])
            if kind is not None:
                out[name] = (name, label, kind)
    # the host perception's estimate (a column of every sweep, not a
    # behaviour's measure): a panel when the rows carry it, beside the
    # behaviour's own shape measure
    for name, label in INSTRUMENT_PLOTS:
        if name in columns and plot_kind(name, columns[name]) == "value":
            out[name] = (name, label, "value")
    return list(out.values())


# sweep columns an instrument watching every run gives (perception/tracker.py)
INSTRUMENT_PLOTS = (("estimate_iou", "host's shape estimate IoU"),)
