"""Host side of aggregation: count the robots that stopped, halt at quorum.

Fed decoded messages (node, kind, fields) like the thesis coordinator and
exposing the same run-facing attributes (found_tick, converged_tick,
delivered_tick, touches, power, leader, segments_now), so every engine,
link and the host process drive it unchanged. The host contract
(firmware_logic/roster.py): it journals a HELLO of a new node, each new
stop (TOUCH), and each report that withdraws a stop (LEAVE, or a HEARTBEAT
whose state is no longer STAY); replaying them in order rebuilds the stops.
"""

from firmware_logic import messages as msg
from .spec import LEAVE, MODELS, STAY
from firmware_logic.roster import Roster

SUBSET_SETUP = ("Stop", "Coordinator")

UNANNOUNCED_STOP = "stop from unannounced node"
UNANNOUNCED_REPORT = "report from unannounced node"
STOP_OUT_OF_RANGE = "stop outside the arena"


class Stop:
    """A robot's stop: its report (TOUCH: seq, robot patch, touched patch,
    power) and the host tick it was accepted at."""

    def __init__(self, node, seq, rx, ry, sx, sy, power, tick):
        self.node = node
        self.seq = seq
        self.rx = rx
        self.ry = ry
        self.sx = sx
        self.sy = sy
        self.power = power
        self.tick = tick


class Coordinator(Roster):
    NOT_SNAPSHOT = Roster.NOT_SNAPSHOT + ("robots", "need")

    def __init__(self, robots, quorum_percent, journal=None, on_reject=None,
                 world_size=None):
        """journal, on_reject: see firmware_logic/roster.py."""
        codes = []
        for m in MODELS:
            codes.append(m[0])
        Roster.__init__(self, tuple(codes), journal, on_reject)
        self.robots = robots
        self.need = (robots * quorum_percent + 99) // 100
        self.world_size = 127 if world_size is None else world_size
        self.touches = []         # one Stop per stopped robot, in order
        self.stopped = {}         # node -> Stop
        self.power = 0
        self.weight = self.need   # what `power` is compared against
        self.leader = 0
        self.found_tick = -1
        self.converged_tick = -1
        self.delivered_tick = -1
        self.duplicates = 0
        self.outbox = []

    def on_message(self, node, kind, f, tick):
        if kind == msg.HELLO:
            self._hello(node, f, tick)
        elif node not in self.nodes:
            self._reject(UNANNOUNCED_STOP if kind == msg.TOUCH else UNANNOUNCED_REPORT,
                         node, f)
        elif kind == msg.TOUCH:
            old = self.stopped.get(node)
            if old is not None and old.seq == f[0]:
                self.duplicates += 1
            elif self.delivered_tick >= 0:
                # the quorum's stops are the result: a robot that left and
                # stopped again before the HALT reached it is acknowledged
                # (it stops retransmitting) but neither counted nor journalled,
                # so the result holds one stop per robot and a replay of the
                # journal rebuilds exactly it
                pass
            elif self._invalid(f):
                self._reject(STOP_OUT_OF_RANGE, node, f)
                return
            else:
                self._record(node, kind, f, tick)
                self._leave(node)      # a new stop withdraws the old one first
                s = Stop(node, f[0], f[1], f[2], f[3], f[4], f[5], tick)
                self.stopped[node] = s
                self.touches.append(s)
                self.power = len(self.touches)
                if self.found_tick < 0:
                    self.found_tick = tick
                    self.leader = node
            self._ack(node, f[0])
        elif kind == LEAVE:
            # only the stop it reported: a stale LEAVE cannot undo a newer stop
            if node in self.stopped and self.stopped[node].seq == f[0]:
                self._record(node, kind, f, tick)
                self._leave(node)
        elif kind == msg.HEARTBEAT:
            if node in self.stopped and f[0] != STAY:
                self._record(node, kind, f, tick)
                self._leave(node)

    def _invalid(self, f):
        w = self.world_size
        for v in (f[1], f[2], f[3], f[4]):
            if v < -w or v > w:
                return True
        return False

    def _leave(self, node):
        # once the quorum is reached the stops it counted are the result: the
        # robots halt and leave their stops then (their HEARTBEATs say halt),
        # which must not empty the mission's record after the fact
        if self.delivered_tick >= 0:
            return
        if node in self.stopped:
            s = self.stopped[node]
            del self.stopped[node]
            self.touches.remove(s)
            self.power = len(self.touches)

    def segments_now(self):
        return []

    # carriers(): none (Roster's): a stopped robot that falls silent still
    # counts towards the quorum

    def status(self):
        if self.delivered_tick >= 0:
            return "quorum reached at tick %d: %d of %d robots stopped; HALT" % (
                self.delivered_tick, len(self.touches), self.robots)
        return "%d of %d robots stopped (quorum %d)" % (len(self.touches), self.robots,
                                                         self.need)

    def quiet(self):
        """True when tick() without a new message would neither send nor change
        anything (a batch engine then skips the call)."""
        return not self.outbox and not self.acks and (
            self.delivered_tick >= 0 or len(self.touches) < self.need)

    def tick(self, tick):
        self._acks_out(self.outbox)
        if self.delivered_tick < 0 and len(self.touches) >= self.need:
            self.converged_tick = tick
            self.delivered_tick = tick
            self.outbox.append((msg.HOST, msg.HALT, (0,)))
        out = self.outbox
        self.outbox = []
        return out

    def clusters(self):
        """Sizes of the groups of stopped robots whose patches touch, largest first."""
        cells = {}
        for s in self.touches:
            cells[(s.rx, s.ry)] = 1
        seen = {}
        sizes = []
        for start in cells:
            if start in seen:
                continue
            todo = [start]
            seen[start] = 1
            n = 0
            while todo:
                x, y = todo.pop()
                n += 1
                for dx in (-1, 0, 1):
                    for dy in (-1, 0, 1):
                        c = (x + dx, y + dy)
                        if c in cells and c not in seen:
                            seen[c] = 1
                            todo.append(c)
            sizes.append(n)
        sizes.sort()
        sizes.reverse()
        return sizes

    def reporters(self):
        """spec.REPORTERS by name: the same counts as the run's measures."""
        return self.measures()

    def measures(self):
        sizes = self.clusters()
        return {"stopped": len(self.touches), "clusters": len(sizes),
                "largest": sizes[0] if sizes else 0}
