"""Scenarios: the world's keys plus the behaviour's own, loaded from TOML.

A scenario file is flat TOML; every key is optional (docs/scenarios.md).
The world's keys (arena, robots, objects, links, faults, activation) are
the fields of `Scenario`; every other key is a parameter the scenario's
behaviour declares in its spec.PARAMS, validated against the range declared
there and read as an attribute like a world key (`sc.<name>`). Unknown keys
and out-of-range values raise ScenarioError naming the key and the allowed
range.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sim_backend import arena, objects, params
from sim_backend.errors import ScenarioError

DEFAULT_BEHAVIOUR = "thesis"

# The firmware's RNG folds a run seed modulo 1,000,003 (firmware_logic/rng.py,
# seed_state), so seed 1,000,004 would silently repeat seed 1. Seeds are held
# to the one range where every seed gives its own run.
SEED_MIN, SEED_MAX = 0, 1_000_002


# Departures from the NetLogo code of Appendix A, each a named choice; the
# first choice is the default (docs/tick-semantics.md, "Departures from
# Appendix A", gives each one's thesis rule and measured effect). "netlogo"
# is always the thesis's rule.
CHOICES: dict[str, tuple[str, ...]] = {
    # Signal centred on the holder's patch for every holder, or on the
    # finder's continuous position once per tick for the last finder (go, Signal)
    "signalMode": ("patch", "netlogo"),
    # uphill ties: first in N, NE, E, ... order, or at random (NetLogo's uphill)
    "uphillTies": ("ordered", "netlogo"),
    # `set field 10` on a leader's patch every tick (go): off, or as NetLogo
    "leaderField": ("off", "netlogo"),
    # delivered when a holder or segment is within 4 of home, or when a holder
    # is within 1 (`distancexy -15 -15 < 1`, which writes tt.txt)
    "arrival": ("within4", "netlogo"),
    # starts redrawn off the object and other robots with a fresh heading, or
    # CreateSwarm's `fd random max-pxcor` keeping the walk's heading
    "starts": ("redraw", "netlogo"),
    # HeadCarefully's probe: the robot does not see itself, or it does, as
    # `any? turtles-on patch-at-heading-and-distance heading 1` counts the
    # caller when the point one ahead lies in its own patch (kernel.SELF_COUNTS)
    "probeSelf": ("skip", "netlogo"),
    # the first go iteration: look for the object before the first move, or
    # move first as go's RandomHead, FindObject, FindField (the behaviour reads it)
    "firstMove": ("look", "netlogo"),
    # uphill's heading: a multiple of 45 degrees, or `towards` the winning
    # patch's centre from the robot's position (kernel.TOWARDS)
    "uphillHeading": ("octant", "netlogo"),
}
# how robots take turns. sync: every robot decides on the
# tick-start world, conflicts resolved at the tick's end (real robots act in
# parallel); netlogo: go's `ask robots`, one robot after another in a random
# order drawn every go iteration, each seeing the moves before it, a robot in
# a field stepping 1 + its MULTI_STEP parameter times (docs/tick-semantics.md, Activation)
CHOICES["activation"] = ("sync", "netlogo")


def check_seed(seed: Any, source: str = "seed") -> int:
    """The seed as an int; ScenarioError naming the range when it is outside."""
    if isinstance(seed, bool) or not isinstance(seed, int):
        raise ScenarioError(f"{source}: expected an integer in {SEED_MIN}..{SEED_MAX}, "
                            f"got {seed!r}")
    if not SEED_MIN <= seed <= SEED_MAX:
        raise ScenarioError(f"{source} {seed}: outside {SEED_MIN}..{SEED_MAX}; the firmware "
                            f"RNG takes seeds modulo {SEED_MAX + 1}, so larger or negative "
                            "seeds would repeat another seed's run")
    return seed


# A dataclass (fields(), replace(), asdict() work on it) whose __init__,
# __repr__, __eq__, __hash__ and frozen __setattr__ are written once below
# for every field: the decorator's generated ones, compiled for these 44
# fields at each import, made this module's import 21 M instructions of
# every command's start-up (3.6 M now). The behaviour is the decorator's
# (frozen=True).
@dataclass(init=False, repr=False, eq=False)
class Scenario:
    """A validated scenario: the world's keys as fields (their defaults the
    default scenario's world), the behaviour's own keys in `params`, read
    as attributes too (`sc.<name>`). Made by load() or validate(); changed
    by replace(), which validates again. Frozen: assigning a field raises
    dataclasses.FrozenInstanceError."""

    name: str = "default"
    description: str = ""
    agents: int = 20             # the thesis's (5.2.4, "Total Robot Population was 20")
    sigRadius: int = 5           # ours: the text gives no base value
    objectWeight: float = 5.0    # ours: the text gives no base value
    object: str = "bar"           # the thesis's DrawObject object 1 (Appendix A)
    # patches run from -worldSize to +worldSize; 18 is the thesis's (3.7, "a grid of
    # 18 x 18 square patches": NetLogo's screen-edge 18, as home at -15, -15 needs)
    worldSize: int = 18
    homeX: int = -15             # the thesis's (Appendix A, PaintHome)
    homeY: int = -15
    objectX: int | None = None   # None: `random 10`, as CreateWorld draws it
    objectY: int | None = None
    maxTicks: int = 20000
    behaviour: str = DEFAULT_BEHAVIOUR   # a name from `touchswarm behaviours` or a folder
    signalMode: str = CHOICES["signalMode"][0]
    uphillTies: str = CHOICES["uphillTies"][0]
    leaderField: str = CHOICES["leaderField"][0]
    arrival: str = CHOICES["arrival"][0]
    starts: str = CHOICES["starts"][0]
    activation: str = CHOICES["activation"][0]
    probeSelf: str = CHOICES["probeSelf"][0]
    firstMove: str = CHOICES["firstMove"][0]
    uphillHeading: str = CHOICES["uphillHeading"][0]
    # -- the arena the user draws (docs/scenarios.md, "Objects and obstacles");
    # objects empty: the flat object/objectX/objectY/objectWeight keys
    objects: tuple = ()          # objects.Piece, the target among them
    obstacles: tuple = ()        # objects.Piece
    # [[library]]: shapes the host's recogniser knows by name beside the
    # built-ins (objects.Piece: name and cells; perception/shapes.py)
    library: tuple = ()
    field: str = "static"        # beacons stay where lit (thesis), or move with holders
    # robots in the carried object's way step aside (NetLogo's turtles
    # overlap, so nothing stopped the thesis's object), or block it ("block")
    crowd: str = "yield"
    wrap: bool = False           # ours; true: a toroidal search phase (NetLogo's default world)
    # faults (sim_backend/faults.py), all off by default; rates are shares of the swarm
    deathRate: float = 0.0       # robots that stop for good at a random tick, holders too
    deadlockRate: float = 0.0    # robots stuck in place for deadlockTicks from a random tick
    deadlockTicks: int = 100
    ignoreFieldRate: float = 0.0  # non-complying: never sense the field
    ignoreHostRate: float = 0.0  # non-complying: drop the host's commands
    randomRate: float = 0.0      # random agents: wander, never claim
    probeMiss: float = 0.0       # chance a probe misses a free segment
    probeGhost: float = 0.0      # chance a probe of an empty patch reports a segment
    fieldNoise: int = 0          # field readings +- up to this much
    faultWindow: int = 1000      # deaths and deadlocks start in ticks 1..faultWindow
    # the link's own faults (bridge/links/canlink.py Faults), over --link can only
    linkLoss: float = 0.0        # chance a frame is lost, each way
    linkDup: float = 0.0         # chance a frame is sent twice
    linkReorder: int = 1         # frames shuffled within windows of this many (1: in order)
    linkDelay: int = 0           # each frame held back 0..linkDelay ticks, drawn per frame
    # several breeds ([[breeds]] tables): each ((key, value), ...) with its count;
    # nodes are numbered breed by breed; empty: one breed, the keys above
    breeds: tuple = ()
    # the behaviour's own keys (its spec.PARAMS), ((name, value), ...) in
    # declaration order; read as attributes: sc.<name> (sim_backend/params.py)
    params: tuple = ()

    def __init__(self, **keys: Any) -> None:
        unknown = keys.keys() - _DEFAULTS.keys()
        if unknown:
            raise TypeError(f"Scenario.__init__() got an unexpected keyword argument "
                            f"{min(unknown)!r}")
        d = self.__dict__
        d.update(_DEFAULTS)
        d.update(keys)
        self.__post_init__()

    def _fields(self) -> tuple:
        d = self.__dict__
        return tuple([d[k] for k in _DEFAULTS])

    def __repr__(self) -> str:
        return "Scenario(" + ", ".join(f"{k}={v!r}" for k, v in zip(_DEFAULTS, self._fields())) \
            + ")"

    def __eq__(self, other: Any) -> bool:       # (`object` here is the field)
        if other.__class__ is not self.__class__:
            return NotImplemented
        return self._fields() == other._fields()

    def __hash__(self) -> int:
        return hash(self._fields())

    def __setattr__(self, name: str, value: Any) -> None:
        raise dataclasses.FrozenInstanceError(f"cannot assign to field {name!r}")

    def __delattr__(self, name: str) -> None:
        raise dataclasses.FrozenInstanceError(f"cannot delete field {name!r}")

    def __post_init__(self) -> None:
        if not self.params:
            object.__setattr__(self, "params", params.defaults(self.behaviour))
        # the parameters by name: a batch's robot constructors read them
        # 10,000s of times (no field: not compared, not written)
        try:
            object.__setattr__(self, "_by_name", dict(reversed(self.params)))
        except (TypeError, ValueError):      # not pairs: validate names what is wrong
            pass

    def __getattr__(self, name: str) -> Any:
        # only reached for names that are no field: the behaviour's parameters
        by_name = self.__dict__.get("_by_name")
        if by_name is not None and name in by_name:
            return by_name[name]
        for key, value in self.__dict__.get("params", ()):
            if key == name:
                return value
        raise AttributeError(f"scenario has no key {name!r} (behaviour "
                             f"{self.__dict__.get('behaviour')!r} declares none)")

    def pieces(self) -> list:
        """The scenario's objects as objects.Piece, the target first."""
        if self.objects:
            return sorted(self.objects, key=lambda p: not p.target)
        if self.object == objects.NONE:
            return []
        at = (None if self.objectX is None or self.objectY is None
              else (self.objectX, self.objectY))
        return [objects.Piece(self.object, tuple(objects.offsets(self.object)), at,
                              self.objectWeight, None, True)]

    def breed_index(self, node: int) -> int:
        """The breed (index into breeds) of robot `node` (1-based); 0 without breeds."""
        start = 1
        for j, b in enumerate(self.breeds):
            start += dict(b)["count"]
            if node < start:
                return j
        return 0

    def breed_name(self, node: int) -> str:
        """The name of robot `node`'s breed ("" without breeds)."""
        return dict(self.breeds[self.breed_index(node)])["name"] if self.breeds else ""

    def for_node(self, node: int) -> "Scenario":
        """The scenario robot `node` lives by: its breed's keys over this one."""
        if not self.breeds:
            return self
        over = dict(self.breeds[self.breed_index(node)])
        mine = tuple((k, over.get(k, v)) for k, v in self.params)
        return dataclasses.replace(self, breeds=(), params=mine)

    @property
    def weight_centi(self) -> int:
        return round(self.objectWeight * 100)

    def to_dict(self) -> dict[str, Any]:
        """Every key: the world's, then the behaviour's (flat, as a file sets them)."""
        d = dataclasses.asdict(self)        # pieces and obstacles as tables, too
        d.update(d.pop("params"))
        return d

    def replace(self, **changes: Any) -> "Scenario":
        return validate(merge(self.to_dict(), changes))


def merge(base: dict[str, Any], changes: dict[str, Any]) -> dict[str, Any]:
    """The keys of `base` with `changes` over them. When the changes name
    another behaviour, the old behaviour's parameters it does not declare
    are left behind (they would be unknown keys of the new one), and so is
    its description, which spoke of the old behaviour's run."""
    old = base.get("behaviour", DEFAULT_BEHAVIOUR)
    new = changes.get("behaviour", old)
    if str(new) != str(old):
        keep = set(params.names(str(new))) if _is_behaviour(new) else set()
        base = {k: v for k, v in base.items()
                if (k in FIELDS and k != "description") or k in keep}
    return {**base, **changes}


def _is_behaviour(ref: Any) -> bool:
    try:
        params.names(str(ref))
    except ScenarioError:
        return False
    return True


# key -> (kind, low, high); None bounds are unchecked. The simulator takes
# swarms far beyond one CAN bus (nodes 1..127, messages.MAX_NODE) and arenas
# beyond the links' 1-byte patch fields; links that carry real frames must
# check a scenario against their own limits.
RANGES: dict[str, tuple[type, Any, Any]] = {
    "agents": (int, 1, 20000),
    "sigRadius": (int, 0, 30),
    "objectWeight": (float, 0.01, 10000.0),
    # 414: 10,000 robots at the default arena's density (arena_presets.scaled_world)
    "worldSize": (int, 10, 420),
    "homeX": (int, -60, 60),
    "homeY": (int, -60, 60),
    "objectX": (int, -60, 60),
    "objectY": (int, -60, 60),
    "maxTicks": (int, 1, 10_000_000),
    "deathRate": (float, 0.0, 1.0), "deadlockRate": (float, 0.0, 1.0),
    "deadlockTicks": (int, 1, 1_000_000), "ignoreFieldRate": (float, 0.0, 1.0),
    "ignoreHostRate": (float, 0.0, 1.0), "randomRate": (float, 0.0, 1.0),
    "probeMiss": (float, 0.0, 1.0), "probeGhost": (float, 0.0, 1.0),
    "fieldNoise": (int, 0, 10), "faultWindow": (int, 1, 10_000_000),
    "linkLoss": (float, 0.0, 0.9), "linkDup": (float, 0.0, 0.9), "linkReorder": (int, 1, 64),
    "linkDelay": (int, 0, 64),
}
# the unit of each numeric world key (figure axes, sim_backend/plots.py)
UNITS: dict[str, str] = {
    "agents": "robots", "sigRadius": "patches", "objectWeight": "weight units",
    "worldSize": "patches from the centre", "homeX": "patches", "homeY": "patches",
    "objectX": "patches", "objectY": "patches", "maxTicks": "ticks",
    "deathRate": "share of robots", "deadlockRate": "share of robots",
    "deadlockTicks": "ticks", "ignoreFieldRate": "share of robots",
    "ignoreHostRate": "share of robots", "randomRate": "share of robots",
    "probeMiss": "probability per probe", "probeGhost": "probability per probe",
    "fieldNoise": "field units", "faultWindow": "ticks", "linkLoss": "probability per frame",
    "linkDup": "probability per frame", "linkReorder": "frames", "linkDelay": "ticks",
}
LINK_FAULT_KEYS = ("linkLoss", "linkDup", "linkReorder", "linkDelay")


def link_faults(sc: "Scenario") -> list[str]:
    """The link fault keys `sc` sets (they need a real link: --link can)."""
    return [k for k in LINK_FAULT_KEYS if getattr(sc, k) != _DEFAULTS[k]]


# every field and its default, in declaration order (Scenario.__init__)
_DEFAULTS: dict[str, Any] = {f.name: f.default for f in dataclasses.fields(Scenario)}
FIELDS = set(_DEFAULTS) - {"params"}
WORLD_KEYS = frozenset(FIELDS)


def _object_name(value: Any) -> str:
    if isinstance(value, bool):
        raise ScenarioError(f"object: expected 1-4 or one of {sorted(objects.SHAPES)}, got {value!r}")
    if isinstance(value, int) and value in objects.THESIS_NUMBERS:
        return objects.THESIS_NUMBERS[value]
    if isinstance(value, str):
        if value.lower() == objects.NONE:
            return objects.NONE
        for name in objects.SHAPES:
            if name.lower() == value.lower():
                return name
    raise ScenarioError(
        f"object: expected 1-4, {objects.NONE!r} or one of {', '.join(sorted(objects.SHAPES))}, "
        f"got {value!r}")


def _behaviour(value: Any) -> Any:
    """The behaviour (sim_backend.registry.Behaviour) a scenario names."""
    from sim_backend import registry

    from sim_backend import words
    try:
        beh = registry.load(str(value))
        words.of(beh)          # its outputs' words, checked before any run
    except registry.BehaviourError as err:
        raise ScenarioError(f"behaviour: {err}") from err
    return beh


def validate(raw: dict[str, Any], source: str = "scenario") -> Scenario:
    behaviour = str(raw.get("behaviour", DEFAULT_BEHAVIOUR))
    beh = _behaviour(behaviour)
    declared = {p.name: p for p in params.declared(behaviour, WORLD_KEYS)}
    unknown = sorted(set(raw) - FIELDS - set(declared))
    if unknown:
        raise ScenarioError(
            f"{source}: unknown key {unknown[0]!r}; the world's keys: {', '.join(sorted(FIELDS))}; "
            f"behaviour {behaviour!r}'s: {', '.join(declared) or 'none'}")
    values: dict[str, Any] = {"behaviour": behaviour}
    own = {name: p.default for name, p in declared.items()}
    raw = arena.parse(raw, values)
    for key, value in raw.items():
        if key == "behaviour":
            continue
        if key in declared:
            own[key] = declared[key].check(value)
        elif key == "object":
            values[key] = _object_name(value)
        elif key in ("name", "description"):
            values[key] = str(value)
        elif key == "breeds":
            values[key] = _breeds(value, source, declared)
        elif key in CHOICES:
            if value not in CHOICES[key]:
                raise ScenarioError(f"{key}: expected one of {', '.join(CHOICES[key])}, "
                                    f"got {value!r}")
            values[key] = value
        elif key in ("objectX", "objectY") and value is None:
            values[key] = None
        else:
            kind, lo, hi = RANGES[key]
            ok_type = isinstance(value, (int, float)) and not isinstance(value, bool)
            if kind is int and ok_type and float(value).is_integer():
                value = int(value)
            if not ok_type or (kind is int and not isinstance(value, int)):
                raise ScenarioError(f"{key}: expected {kind.__name__} in {lo}..{hi}, got {value!r}")
            if value != value or value < lo or value > hi:     # NaN compares False
                raise ScenarioError(f"{key}: {value!r} is outside the allowed range {lo}..{hi}")
            values[key] = kind(value)
    values["params"] = tuple(own.items())
    if values.get("breeds"):
        total = sum(dict(b)["count"] for b in values["breeds"])
        if "agents" in raw and values["agents"] != total:
            raise ScenarioError(f"agents: {values['agents']} differs from the breeds' counts, "
                                f"which add up to {total}; give one of them")
        values["agents"] = total
    sc = Scenario(**values)
    if sc.activation != "sync":
        from sim_backend import faults
        if faults.active(sc):
            # fault draws and deaths are keyed to the synchronous tick
            raise ScenarioError(f"activation: {sc.activation!r} runs without faults; faults "
                                "(deathRate, probeMiss, ...) need activation \"sync\"")
    if sc.wrap and sc.sigRadius > sc.worldSize:
        # a wider field would meet itself round the torus, reaching a patch twice
        raise ScenarioError(f"wrap: sigRadius {sc.sigRadius} exceeds worldSize "
                            f"{sc.worldSize}; on the torus a field must not reach round "
                            "to itself: lower sigRadius or enlarge worldSize")
    if sc.objects or sc.obstacles:
        arena.check(sc)
    else:
        _check_consistency(sc)
    if (sc.objectX is None) != (sc.objectY is None):
        # the world draws the anchor whole (CreateWorld's two `random 10`s) or takes it whole
        raise ScenarioError(f"objectX, objectY: set both or neither (got objectX={sc.objectX}, "
                            f"objectY={sc.objectY})")
    # the behaviour's own rules over the whole scenario (its __init__.check)
    check = getattr(beh.package, "check", None)
    if check is not None:
        try:
            check(sc)
        except ValueError as err:
            raise ScenarioError(str(err)) from err
    return sc


def _breeds(value: Any, source: str, declared: dict[str, params.Param]) -> tuple:
    """[[breeds]] tables (or the tuple form to_dict gives back) as a tuple of
    ((key, value), ...) per breed; a breed sets `count`, `name` and any of
    the behaviour's parameters, each checked like the scenario's own."""
    if isinstance(value, dict) or not isinstance(value, (list, tuple)):
        raise ScenarioError("breeds: expected a list of tables ([[breeds]] with count = N, "
                            "and parameters of the behaviour), got {value!r}".format(value=value))
    out = []
    for j, b in enumerate(value, 1):
        d = dict(b) if isinstance(b, (dict, list, tuple)) else None
        if d is None or "count" not in d:
            raise ScenarioError(f"breeds #{j}: expected a table with count = N, got {b!r}")
        unknown = sorted(set(d) - set(declared) - {"count", "name"})
        if unknown:
            raise ScenarioError(f"breeds #{j}: unknown key {unknown[0]!r}; a breed sets count, "
                                f"name, {', '.join(declared)}")
        count = d["count"]
        if isinstance(count, bool) or not isinstance(count, int) or not 1 <= count <= 20000:
            raise ScenarioError(f"breeds #{j}: count: expected int in 1..20000, got {count!r}")
        row = [("count", count), ("name", str(d.get("name", f"breed{j}")))]
        row += [(k, declared[k].check(d[k])) for k in declared if k in d]
        out.append(tuple(row))
    return tuple(out)


def holders_needed(sc: Scenario, weight_centi: int) -> int | None:
    """The fewest robots that must hold an object of this weight, by the
    behaviour's own rule (its __init__.holders_needed); None when the
    behaviour holds no objects by weight."""
    rule = getattr(_behaviour(sc.behaviour).package, "holders_needed", None)
    return None if rule is None else int(rule(sc, weight_centi))


def holders_within_swarm(sc: Scenario, weight_centi: int, key: str) -> int | None:
    """holders_needed, refused in one line naming `key` when the whole swarm
    together cannot hold the weight."""
    needed = holders_needed(sc, weight_centi)
    if needed is not None and needed > sc.agents:
        raise ScenarioError(
            f"{key}: weight {weight_centi / 100:g} is more than all {sc.agents} robots can hold "
            f"together (behaviour {sc.behaviour!r}); lower the weight or add robots")
    return needed


def _check_empty_world(sc: Scenario) -> None:
    """object = "none": nothing to place, nothing a behaviour could carry."""
    if holders_needed(sc, sc.weight_centi) is not None:
        raise ScenarioError(f"object: behaviour {sc.behaviour!r} carries an object by its weight; "
                            f"{objects.NONE!r} leaves it none: name a shape")
    arena.check_home(sc)
    arena.check_crowd(sc, 0)


def _check_consistency(sc: Scenario) -> None:
    shares = (sc.deathRate + sc.ignoreFieldRate + sc.ignoreHostRate + sc.randomRate)
    if shares > 1.0 + 1e-9:
        raise ScenarioError(f"deathRate + ignoreFieldRate + ignoreHostRate + randomRate: "
                            f"{shares:g} exceeds 1 (they are disjoint shares of the swarm)")
    w = sc.worldSize
    if not sc.pieces():
        _check_empty_world(sc)
        return
    offs = objects.offsets(sc.object)
    xs = [x for x, _ in offs]
    ys = [y for _, y in offs]
    # the anchor range: fixed, or CreateWorld's `random 10`
    ax = (sc.objectX, sc.objectX) if sc.objectX is not None else (0, 9)
    ay = (sc.objectY, sc.objectY) if sc.objectY is not None else (0, 9)
    # one free patch all round, so a robot can stand beside every edge
    lo_x, hi_x = ax[0] + min(xs), ax[1] + max(xs)
    lo_y, hi_y = ay[0] + min(ys), ay[1] + max(ys)
    if lo_x < -w + 1 or hi_x > w - 1 or lo_y < -w + 1 or hi_y > w - 1:
        raise ScenarioError(
            f"object: {sc.object!r} at anchor x {ax[0]}..{ax[1]}, y {ay[0]}..{ay[1]} spans "
            f"x {lo_x}..{hi_x}, y {lo_y}..{hi_y}, which does not fit the arena "
            f"{-w + 1}..{w - 1} (worldSize={w}); enlarge worldSize or move objectX/objectY")
    arena.check_home(sc)
    cells = set(objects.offsets(sc.object))
    hx, hy = sc.homeX, sc.homeY
    for x, y in cells:
        # the anchor that brings this cell nearest home, each axis clamped
        # into its range (the squares add up): every anchor's distance without
        # trying all 100 (1,600 tries were a third of a scenario's check)
        ox = min(max(hx - x, ax[0]), ax[1])
        oy = min(max(hy - y, ay[0]), ay[1])
        if (x + ox - hx) ** 2 + (y + oy - hy) ** 2 < 16:
            raise ScenarioError(
                f"object: {sc.object!r} at anchor x {ax[0]}..{ax[1]}, y "
                f"{ay[0]}..{ay[1]} may come within 4 patches of home "
                f"({sc.homeX}, {sc.homeY}); it must stay at least 4 patches away: "
                "move objectX/objectY or homeX/homeY")
    needed = holders_within_swarm(sc, sc.weight_centi, "objectWeight")
    if needed is not None:
        reach = objects.touchable(sc.object)
        if needed > reach:
            raise ScenarioError(
                f"objectWeight: {sc.objectWeight} needs {needed} robots holding, but "
                f"{sc.object!r} has only {reach} reachable segments; lower objectWeight")
    arena.check_crowd(sc, len(cells))


_BARE_KEY = frozenset("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789_-")


def flat_toml(text: str) -> dict[str, Any] | None:
    """The table of a flat TOML text whose lines are each blank, a comment,
    or `key = value` with a bare key and a plain value: a string without
    escapes, an integer or decimal without underscores, true or false (the
    built-in scenarios, --set values). None for any other text, which
    tomllib reads (its import and first parse are 9 M instructions, more
    than a run's scenario needs)."""
    out: dict[str, Any] = {}
    for line in text.replace("\r\n", "\n").split("\n"):
        if not line.replace("\t", " ").isprintable():
            return None         # a control character (tomllib's error), or rare text
        line = line.strip(" \t")
        if not line or line[0] == "#":
            continue
        key, eq, rest = line.partition("=")
        key, rest = key.rstrip(" \t"), rest.lstrip(" \t")
        if not eq or not key or not set(key) <= _BARE_KEY or key in out:
            return None
        if rest[:1] == '"':
            end = rest.find('"', 1)
            if end < 0 or "\\" in rest[:end]:
                return None
            value: Any = rest[1:end]
            tail = rest[end + 1:].lstrip(" \t")
        else:
            word, hash_, comment = rest.partition("#")
            value, tail = _plain(word.rstrip(" \t")), hash_ + comment
            if value is None:
                return None
        if tail and tail[0] != "#":
            return None
        out[key] = value
    return out


def _plain(word: str) -> bool | int | float | None:
    """A TOML boolean, integer or decimal in its plainest spelling; None
    for anything else."""
    if word in ("true", "false"):
        return word == "true"
    whole, dot, frac = word.lstrip("+-").partition(".")
    if not whole.isdigit() or not whole.isascii() or (whole[0] == "0" and len(whole) > 1) \
            or len(word) - len(word.lstrip("+-")) > 1:
        return None
    if not dot:
        return int(word)
    if not frac.isdigit() or not frac.isascii():
        return None
    return float(word)


# the package's own folder, not importlib.resources: that module imports
# tempfile, zipfile and shutil, a tenth of `touchswarm run`'s imports, and the
# package is always installed as files (wheel or editable)
SCENARIOS_DIR = Path(__file__).resolve().parent / "scenarios"


def builtin_names() -> list[str]:
    return sorted(p.name[:-5] for p in SCENARIOS_DIR.iterdir() if p.name.endswith(".toml"))


def load(spec: str | Path | None = None) -> Scenario:
    """A scenario by built-in name or by path to a TOML file."""
    if spec is None:
        spec = "default"
    if not str(spec).strip():
        raise ScenarioError(f"scenario: an empty name; expected a built-in "
                            f"({', '.join(builtin_names())}) or a .toml file")
    path = Path(spec)
    if str(spec) in builtin_names():
        text = (SCENARIOS_DIR / f"{spec}.toml").read_text(encoding="utf-8")
        source = f"scenario {spec!r}"
    elif path.suffix == ".toml" or path.exists():
        from sim_backend.textfile import TextFileError, read_small_text
        try:
            text = read_small_text(path)
        except TextFileError as err:
            raise ScenarioError(f"scenario file {str(path)!r}: {err}; expected a TOML "
                                f"file") from None
        source = str(path)
    else:
        raise ScenarioError(f"scenario: {str(spec)!r} is neither a built-in "
                            f"({', '.join(builtin_names())}) nor a .toml file")
    raw = flat_toml(text)
    if raw is None:
        import tomllib
        try:
            raw = tomllib.loads(text)
        except tomllib.TOMLDecodeError as err:
            raise ScenarioError(f"{source}: not valid TOML: {err}") from err
    if "behaviour" in raw:
        # a file names, never imports: a folder only when the user trusted it
        from sim_backend import registry
        if source == str(path):       # a file: its folder, relative to the file
            raw["behaviour"] = registry.beside(raw["behaviour"], path.resolve().parent)
        try:
            registry.named_by_data(raw["behaviour"], f"scenario file {source!r}")
        except registry.BehaviourError as err:
            raise ScenarioError(str(err)) from None
    return validate(raw, source)
