"""Host side of aggregation: count the robots that stopped, halt at quorum.

Fed decoded messages (node, kind, fields) like the thesis coordinator and
exposing the same run-facing attributes (found_tick, converged_tick,
delivered_tick, touches, power, leader, segments_now), so every engine,
link and the host process drive it unchanged.
"""

from firmware_logic import messages as msg
from firmware_logic.behaviours.aggregate.spec import LEAVE, STAY

SUBSET_SETUP = ("Stop", "Coordinator")


class Stop:
    def __init__(self, node, seq, rx, ry, sx, sy, power, tick):
        self.node = node
        self.seq = seq
        self.rx = rx
        self.ry = ry
        self.sx = sx
        self.sy = sy
        self.power = power
        self.tick = tick


class Coordinator:
    def __init__(self, robots, quorum_percent, journal=None):
        self.robots = robots
        self.need = (robots * quorum_percent + 99) // 100
        self.journal = journal
        self.nodes = {}
        self.touches = []         # one Stop per stopped robot, in order
        self.stopped = {}         # node -> Stop
        self.power = 0
        self.weight = self.need   # what `power` is compared against
        self.leader = 0
        self.found_tick = -1
        self.converged_tick = -1
        self.delivered_tick = -1
        self.duplicates = 0
        self.rejected = {}
        self.outbox = []

    def on_message(self, node, kind, f, tick):
        if kind == msg.HELLO:
            self.nodes[node] = (f[0], f[1])
            self.outbox.append((node, msg.ACK, (0,)))
        elif kind == msg.TOUCH:
            if node not in self.nodes:
                self.rejected["stop from unannounced node"] = \
                    self.rejected.get("stop from unannounced node", 0) + 1
                return
            old = self.stopped.get(node)
            if old is not None and old.seq == f[0]:
                self.duplicates += 1
            else:
                s = Stop(node, f[0], f[1], f[2], f[3], f[4], f[5], tick)
                if self.journal is not None:
                    self.journal(s)
                self._leave(node)
                self.stopped[node] = s
                self.touches.append(s)
                self.power = len(self.touches)
                if self.found_tick < 0:
                    self.found_tick = tick
                    self.leader = node
            self.outbox.append((node, msg.ACK, (f[0],)))
        elif kind == LEAVE:
            # only the stop it reported: a stale LEAVE cannot undo a newer stop
            if node in self.stopped and self.stopped[node].seq == f[0]:
                self._leave(node)
        elif kind == msg.HEARTBEAT:
            if node in self.stopped and f[0] != STAY:
                self._leave(node)

    def _leave(self, node):
        if node in self.stopped:
            s = self.stopped.pop(node)
            self.touches.remove(s)
            self.power = len(self.touches)

    def restore(self, stops):
        for s in stops:
            if s.node not in self.stopped:
                self.stopped[s.node] = s
                self.touches.append(s)
        self.power = len(self.touches)

    def segments_now(self):
        return []

    def quiet(self):
        """True when tick() without a new message would neither send nor change
        anything (a batch engine then skips the call)."""
        return not self.outbox and (self.delivered_tick >= 0 or len(self.touches) < self.need)

    def tick(self, tick):
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

    def measures(self):
        sizes = self.clusters()
        return {"stopped": len(self.touches), "clusters": len(sizes),
                "largest": sizes[0] if sizes else 0}
