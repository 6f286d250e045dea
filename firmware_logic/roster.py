"""What every host coordinator does with the robots it hears, whatever the
behaviour, and what the host process relies on (the host contract,
docs/writing-a-behaviour.md "What the host needs"):

- nodes announce themselves with HELLO; a HELLO that changes a known node's
  model or power is refused; each node gets at most one ACK per tick however
  many frames carry its id (no amplification); every refused report is
  counted by reason and passed to `on_reject`;
- `journal(node, kind, fields, tick)` is called for every report that
  changed what the coordinator knows, after its checks and BEFORE its ACK
  (the host process makes it durable in the layout messages.MESSAGES
  declares for `kind`);
- `replay(node, kind, fields, tick)` re-applies a journalled report to a
  fresh coordinator: the same checks as on arrival (an older host's journal
  may hold a report a newer one refuses), no journal call, no ACK;
- `snapshot()` / `adopt(state)`: the coordinator's scalar state, which the
  host journals with each decision and a resumed host adopts at that point of
  the replay, so it never makes a decision twice;
- `decision(before, out)`: whether the tick that turned `snapshot()` `before`
  into the present state and produced the commands `out` is a decision to
  journal before `out` is sent, as (kind, text) or None;
- `done()`: the mission is over (the host repeats HALT, then exits);
  `carriers()`: robots the mission cannot go on without (liveness);
  `status()`: one line on where the mission stands; `quiet()`: tick()
  without a new message would neither send nor change anything (the host
  then skips the snapshot; a batch engine skips the call).

A behaviour's Coordinator derives from Roster and overrides what its
mission needs (the thesis: decision names and carriers).
"""

from firmware_logic import messages as msg

SUBSET_SETUP = ("Roster",)    # host side: may allocate

# How a mission ended (the host's summary `outcome`, docs/outputs.md "Host
# outcomes"); only DELIVERED is a success (exit status 0).
DELIVERED = "delivered"  # the coordinator's own model has the object home: a delivered tick
HALTED = "halted"        # the coordinator ended it without delivering and halted the swarm
STALLED = "stalled"      # no progress: the object stuck (the thesis's stall) or the robots silent
STOPPED = "stopped"      # stopped from outside before it ended: a signal, a tick limit
OUTCOMES = (DELIVERED, HALTED, STALLED, STOPPED)

BAD_HELLO = "hello out of range"
CHANGED_HELLO = "hello changes model or power"


def _ints(t):
    for x in t:
        if not isinstance(x, int):
            return False
    return True


class Roster:
    # attributes snapshot() leaves out: configuration (from the command line)
    # and this process's own counters
    # and what the replayed reports rebuild (a report refused on replay must
    # not come back through a snapshot)
    NOT_SNAPSHOT = ("models", "world_size", "duplicates", "weight", "power", "leader",
                    "found_tick")
    # attributes whose change alone is no decision (a resend of a command)
    VOLATILE = ()

    def __init__(self, models, journal=None, on_reject=None):
        """models: the movement model codes a HELLO may announce.
        journal: callable(node, kind, fields, tick), see above.
        on_reject: callable(reason, node, fields, kind) for each refused
        report (kind 0: the report being handed over, as the caller knows)."""
        self.models = models
        self.journal = journal
        self.on_reject = on_reject
        self.nodes = {}          # node -> (model, power)
        self.acks = {}           # node -> seq of the one ACK it gets this tick
        self.rejected = {}       # reason -> count

    def _hello(self, node, f, tick):
        model, power = f[0], f[1]
        known = self.nodes.get(node)
        if known is None:
            if model not in self.models or power < 1:
                self._reject(BAD_HELLO, node, f)
                return
            self._record(node, msg.HELLO, f, tick)
            self.nodes[node] = (model, power)
        elif known != (model, power):
            # a robot's model and power do not change while it runs; taking
            # the new values would re-weigh its report, and the journal (which
            # holds the first HELLO) and memory would disagree after a resume
            self._reject(CHANGED_HELLO, node, f)
            return
        self._ack(node, 0)

    def _record(self, node, kind, f, tick):
        """A report changed what this coordinator knows: journal it (before
        its ACK, which the caller queues afterwards)."""
        if self.journal is not None:
            self.journal(node, kind, tuple(f), tick)

    def _reject(self, reason, node=0, f=(), kind=0):
        """kind: the refused report's, when it was not judged as it was
        handed over (a report held for the tick's end)."""
        self.rejected[reason] = self.rejected.get(reason, 0) + 1
        if self.on_reject is not None:
            self.on_reject(reason, node, f, kind)

    def _ack(self, node, seq):
        # at most one ACK per node per tick, however many frames it (or a
        # forger using its id) sent: the host must not amplify a flood. A
        # report's ACK wins over the HELLO's: the robot takes any ACK as the
        # HELLO's too (a report is only accepted from an announced node).
        if seq or node not in self.acks:
            self.acks[node] = seq

    def _acks_out(self, outbox):
        """Queue this tick's ACKs on `outbox`."""
        if self.acks:
            for node, seq in self.acks.items():
                outbox.append((node, msg.ACK, (seq,)))
            self.acks = {}

    # -- the host contract -------------------------------------------------------

    def replay(self, node, kind, f, tick):
        journal = self.journal
        self.journal = None
        self.on_message(node, kind, f, tick)
        self.journal = journal
        self.acks = {}           # the robot had its ACK, or retransmits for one

    def snapshot(self):
        """The scalar state: int attributes and tuples of ints (a
        coordinator's state is integers, like everything on the link),
        JSON-ready (tuples as lists)."""
        out = {}
        for k, v in self.__dict__.items():
            if k in self.NOT_SNAPSHOT:
                continue
            if isinstance(v, int):
                out[k] = v
            elif isinstance(v, tuple) and _ints(v):
                out[k] = list(v)
        return out

    def adopt(self, state):
        """Set a snapshot's attributes back; returns the names it did not know."""
        unknown = []
        for k, v in state.items():
            if k in self.NOT_SNAPSHOT or not hasattr(self, k):
                unknown.append(k)
            elif isinstance(getattr(self, k), tuple):
                setattr(self, k, tuple(v))
            else:
                setattr(self, k, v)
        return unknown

    def decision(self, before, out):
        """(kind, text) when the tick changed the snapshot (beyond VOLATILE)
        or sent a HALT; kind is the first command's message name, else
        "state"."""
        after = self.snapshot()
        changed = False
        for k, v in after.items():
            if k not in self.VOLATILE and before.get(k) != v:
                changed = True
        halts = 0
        first = ""
        for m in out:
            if m[1] == msg.HALT:
                halts += 1
            if m[1] != msg.ACK and not first:
                first = msg.SCHEMA[m[1]][0].lower()
        if not changed and not halts:
            return None
        kind = first or "state"
        return kind, "%s: %s" % (kind, self.status())

    def done(self):
        return self.delivered_tick >= 0

    def ended(self):
        """How the coordinator ended the mission: DELIVERED (a delivered
        tick), HALTED (done without one; a behaviour may say STALLED), or ""
        while it goes on."""
        if self.delivered_tick >= 0:
            return DELIVERED
        return HALTED if self.done() else ""

    def carriers(self):
        return []

    def quiet(self):
        return False

    def status(self):
        if self.done():
            return "done at tick %d" % self.delivered_tick
        return "%d reports held, %d of %d" % (len(self.touches), self.power, self.weight)
