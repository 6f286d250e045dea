"""The host's decision to transport only what it recognises as the target
(scenario `recognise = true`, docs/perception.md "The decision").

A mixin of the thesis Coordinator, off unless `recognition()` is called.
When on, the coordinator is not told the target's cells: it accepts every
plausible touch, groups the touched segments into clusters (segments on
one object of the host's map, when it has one, or within GAP patches of
each other, transitively: one object each), and asks a
`decider` the host injects (a callable(cells, free) -> the permille
confidence that the cluster is the target; perception/decide.py backs
it with the Bayesian recogniser) about each cluster whose touches changed,
and again every DECIDE_EVERY ticks while it is undecided and the free
evidence grew. Then:

- a cluster recognised as not the target (1000 - p >= confidence): its
  holders get RELEASE (let go, search on, claim nothing in the cluster's box
  for HOLDOFF = spec.RELEASE_TICKS ticks); their touches leave the power total; the release is
  journalled, so a resumed host replays it;
- a cluster recognised as the target (p >= confidence) whose holders' power
  reaches the weight: the transport begins, and every other cluster is
  released (there is one target).

The released touches stay evidence: a later cluster near them is judged
with them (so a wrong release is corrected by the touches that follow). A
touch during the transport anywhere off the carried cluster is released at
once. A holder that missed its
RELEASE says so in its next HEARTBEAT (state HOLD) and gets it again.

Host-side logic in the firmware subset (integers, no imports beyond the
package): it runs in every host process unchanged.
"""

from . import spec
from firmware_logic.roster import Roster

SUBSET_SETUP = ("Recognising",)   # host side: may allocate

GAP = 3            # touched segments this close (Chebyshev) are one object
MARGIN = 2         # patches a RELEASE box reaches beyond a cluster's touches
HOLDOFF = spec.RELEASE_TICKS   # ticks a released robot leaves that box alone
DECIDE_EVERY = 32  # ticks between two questions about one undecided cluster
BYTE = 127         # a RELEASE box travels in signed bytes


class Recognising:
    # rebuilt by the journal's replay (touches, releases), or configuration
    RECOGNITION_NOT_SNAPSHOT = ("recognise", "confidence", "releases")

    def setup_recognition(self):
        """Recognition off (the default): the coordinator is as before."""
        self.recognise = 0
        self.confidence = 1000     # permille
        self.decider = None        # the host's callable(cells, free) -> permille
        self.target_tick = -1      # first tick a cluster passed as the target
        self.target_cells = []     # that cluster's evidence cells then
        self.target_p = -1         # its confidence then, permille
        self.releases = 0          # RELEASE commands (live and replayed)
        self.refused = {}          # world cell of a released touch -> 1
        self.released = {}         # node -> the RELEASE fields it was sent last
        self.verdicts = {}         # cluster nodes -> (permille, tick, free cells seen)
        self.free_seen = {}        # world cell a robot reported standing on -> 1
        self.body = None           # the map's cells of the carried object, when known
        self.objects = None        # the map: each object's cells (recognition())

    def recognition(self, confidence, objects=None):
        """Decide by recognition. confidence: permille a verdict needs (> 500).
        objects: the host's map, each object's cells (where things stand, not
        which is the target), to plan the carried object's whole footprint
        round the others; None in an open arena."""
        self.recognise = 1
        self.confidence = confidence
        self.objects = objects

    # -- hooks the Coordinator calls ----------------------------------------------

    def _ready(self, tick):
        """Whether the transport begins now."""
        if self.recognise:
            return self._decide(tick)
        return self.touches and self.power >= self.weight

    def _seen(self, node, f):
        """A HEARTBEAT (state, x, y, ...): its cell is free evidence; a
        released holder still holding missed its RELEASE and gets it again."""
        if not self.recognise:
            return
        if f[0] == spec.HOLD and node in self.released and node not in self.by_node:
            self._send(node, spec.RELEASE, self.released[node])
        if self.converged_tick < 0:
            self.free_seen[((f[1] + 128) >> 8, (f[2] + 128) >> 8)] = 1

    def _stray(self, t, tick):
        """A touch accepted during the transport off the carried cluster is
        another object's: released at once."""
        if self.recognise and self.converged_tick >= 0:
            if self.body is not None and (t.sx, t.sy) in self.body:
                return                 # the carried object, as the map has it
            g = [t]
            if not self._near(g, self.touches, t):
                self._release_group(g, tick)

    def replay(self, node, kind, f, tick):
        if kind == spec.RELEASE:
            self._apply_release(node, f)
            return
        Roster.replay(self, node, kind, f, tick)

    def wants_decider(self):
        """Whether the host must give this coordinator its decider
        (perception/decide.py equip, named by HOST_EQUIP)."""
        return self.recognise and self.decider is None

    def truth_measures(self, target):
        """What only the simulator can measure (it knows the target's cells,
        the host is not told them): whether the transport began on a cluster
        with no touch on the target."""
        if not self.recognise:
            return {}
        wrong = False
        if self.converged_tick >= 0:
            wrong = True
            for t in self.touches:
                if (t.sx, t.sy) in target:
                    wrong = False
        return {"wrong_transport": wrong}

    def recognition_measures(self):
        if not self.recognise:
            return {}
        return {"target_tick": self.target_tick if self.target_tick >= 0 else None,
                "target_permille": self.target_p if self.target_p >= 0 else None,
                "releases": self.releases}

    # -- the decision --------------------------------------------------------------

    def _decide(self, tick):
        groups = self._clusters()
        best = None
        best_p = -1
        for g in groups:
            p = self._verdict(g, tick)
            if p < 0:
                continue
            if 1000 - p >= self.confidence:
                self._release_group(g, tick)
            elif p >= self.confidence and p > best_p:
                best = g
                best_p = p
        if best is None:
            return False
        if self.target_tick < 0:
            self.target_tick = tick
            self.target_p = best_p
            # the evidence the verdict was given on: the host's perception
            # reports this verdict as the run's (perception/tracker.py)
            self.target_cells = self._evidence(best)
        power = 0
        for t in best:
            power += t.power
        if power < self.weight:
            return False
        for g in groups:
            if g is not best and g[0].node in self.by_node:
                self._release_group(g, tick)
        self.body = self._map_object(best)
        if self.body is not None and self.closed is not None:
            self.closed = self.closed - self.body    # the map blocks the others only
        return True

    def _verdict(self, g, tick):
        """The decider's permille for cluster g, asked again only when its
        touches changed, or it is undecided, DECIDE_EVERY ticks passed and
        more free cells were seen; -1 without a decider."""
        cells = self._evidence(g)
        key = []
        for t in g:
            key.append(t.node)
        key.sort()
        key.append(len(cells))
        key = tuple(key)
        v = self.verdicts.get(key)
        if v is not None:
            decided = v[0] >= self.confidence or 1000 - v[0] >= self.confidence
            if decided or tick - v[1] < DECIDE_EVERY or len(self.free_seen) == v[2]:
                return v[0]
        if self.decider is None:
            return -1
        p = int(self.decider(cells, self.free_seen))
        p = 0 if p < 0 else 1000 if p > 1000 else p
        self.verdicts[key] = (p, tick, len(self.free_seen))
        return p

    def _clusters(self):
        """The accepted touches grouped by object: segments within GAP of one
        another (transitively), in order of their first touch."""
        groups = []
        for t in self.touches:
            home = None
            for g in groups:
                if g and self._near(g, g, t):
                    if home is None:
                        g.append(t)
                        home = g
                    else:
                        home.extend(g)
                        del g[:]
            if home is None:
                groups.append([t])
        out = []
        for g in groups:
            if g:
                out.append(g)
        return out

    def _near(self, g, pool, t):
        """Whether touch t's segment lies within GAP of any segment in pool,
        or on the same object of the host's map (in the object's frame: the
        carried cluster's touches stay together)."""
        a = self._on_map(t)
        for u in pool:
            if u is not t:
                if abs(u.sx - t.sx) <= GAP and abs(u.sy - t.sy) <= GAP:
                    return True
                if a >= 0 and self._on_map(u) == a:
                    return True
        return False

    def _on_map(self, t):
        """The index of the map's object under t's segment, -1 if none."""
        if self.objects is not None:
            j = 0
            while j < len(self.objects):
                if (t.sx, t.sy) in self.objects[j]:
                    return j
                j += 1
        return -1

    def _evidence(self, g):
        """Cluster g's touched cells, with the released touches near them:
        evidence about one object adds up over releases (a wrong release
        is corrected by the touches that follow it)."""
        cells = []
        for t in g:
            cells.append((t.sx + t.mx, t.sy + t.my))
        n = len(cells)
        for c in self.refused:
            if c in cells:
                continue
            j = 0
            while j < n:
                if abs(c[0] - cells[j][0]) <= GAP and abs(c[1] - cells[j][1]) <= GAP:
                    cells.append(c)
                    break
                j += 1
        return cells

    def _release_group(self, g, tick):
        """RELEASE every holder of cluster g: the box round its segments (and
        the released ones near them, and the map's object under them when
        the host has a map) widened by MARGIN."""
        x0 = y0 = BYTE
        x1 = y1 = -BYTE
        cells = self._evidence(g)
        if self.converged_tick < 0:
            body = self._map_object(g)
            if body is not None:
                for c in body:
                    cells.append(c)
        for x, y in cells:
            x0 = min(x0, x - MARGIN)
            y0 = min(y0, y - MARGIN)
            x1 = max(x1, x + MARGIN)
            y1 = max(y1, y + MARGIN)
        f = (max(x0, -BYTE), max(y0, -BYTE), min(x1, BYTE), min(y1, BYTE))
        nodes = []
        for t in g:
            nodes.append(t.node)
        for node in nodes:
            # journalled before it is sent: a resumed host replays the release
            self._record(node, spec.RELEASE, f, tick)
            self._apply_release(node, f)
            self._send(node, spec.RELEASE, f)

    def _apply_release(self, node, f):
        """The node's touch leaves the touch set and the power total (live
        and on replay)."""
        t = self.by_node.get(node)
        if t is not None:
            del self.by_node[node]
            self.touches.remove(t)
            self.power -= t.power
            self.refused[(t.sx + t.mx, t.sy + t.my)] = 1
        self.released[node] = tuple(f)
        self.releases += 1
        if node == self.leader:
            # the first finder held a decoy: the first remaining holder leads
            self.leader = 0
            if self.touches:
                lead = self.touches[0]
                self.leader = lead.node
                self.leader_x = lead.rx
                self.leader_y = lead.ry

    def _map_object(self, g):
        """The map's cells of the object cluster g touched (None without a
        map or when no map object holds its segments)."""
        if self.objects is None:
            return None
        for cells in self.objects:
            for t in g:
                if (t.sx, t.sy) in cells:
                    return cells
        return None
