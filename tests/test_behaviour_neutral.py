"""A user's behaviour is as good as ours: nothing under sim_backend/
or bridge/ names a shipped behaviour's parameter or state; those live in the
behaviour's folder. The names are read from the behaviours' own spec.py, so a
parameter added to the thesis is checked without touching this test.

The thesis's own studies (its Graphs 1-4 and Figures 22-24, the faults and
breeds sweeps) are data in its folder (firmware_logic/behaviours/thesis/
studies.py); sim_backend/studies.py and the figure kinds of plots.py take
every column from them, so no file is let off.
"""

from __future__ import annotations

import re
from pathlib import Path

from sim_backend import registry
from sim_backend import scenario

ROOT = Path(__file__).resolve().parents[1]
IMPORT = re.compile(r"^\s*(from|import)\s")


def _names() -> tuple[set[str], set[str]]:
    params: set[str] = set()
    states: set[str] = set()
    for name in ("thesis", "aggregate"):
        spec = registry.load(name).spec
        params |= {row[0] for row in spec.PARAMS}
        states |= set(spec.STATES)
    # "halt" is every behaviour's state (the host's contract); world keys such
    # as "field" are the world's own words
    states -= {"halt"} | set(scenario.FIELDS)
    return params - set(scenario.FIELDS), states


def _offences(path: Path, params: set[str], states: set[str], root: Path = ROOT) -> list[str]:
    param = re.compile(r"(?<![A-Za-z0-9_])(" + "|".join(sorted(params)) +
                       r")(?![A-Za-z0-9_(]|\.py)")
    state = re.compile(r"[\"'](" + "|".join(sorted(states)) + r")[\"']")
    found = []
    for n, line in enumerate(path.read_text().splitlines(), 1):
        if IMPORT.match(line):
            continue
        for m in (param.search(line), state.search(line)):
            if m:
                found.append(f"{path.relative_to(root)}:{n}: {m.group(0)!r}: {line.strip()}")
    return found


def test_the_names_are_read_from_the_behaviours() -> None:
    params, states = _names()
    assert {"fieldDefiance", "movementModel", "quorum", "recognise"} <= params
    assert {"grasp", "carry", "climb", "stay"} <= states


def test_the_check_finds_a_thesis_parameter_where_it_does_not_belong(tmp_path: Path) -> None:
    params, states = _names()
    bad = tmp_path / "sim_backend" / "probe.py"
    bad.parent.mkdir()
    bad.write_text('x = sc.fieldDefiance\nif s == "carry":\n    pass\ny = recognise(e)\n')
    found = _offences(bad, params, states, root=tmp_path)
    assert len(found) == 2 and "fieldDefiance" in found[0] and "carry" in found[1]


def test_sim_backend_and_bridge_name_no_behaviours_parameter_or_state() -> None:
    params, states = _names()
    found = []
    for top in ("sim_backend", "bridge"):
        for path in sorted((ROOT / top).rglob("*.py")):
            found += _offences(path, params, states)
    assert not found, "\n".join(found)
