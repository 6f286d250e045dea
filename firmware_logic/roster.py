"""What every host coordinator does with the robots it hears, whatever the
behaviour: nodes announce themselves with HELLO (journalled before their
ACK; a HELLO that changes a known node's model or power is refused), each
node gets at most one ACK per tick however many frames carry its id (no
amplification), and every refused report is counted by reason.

A behaviour's Coordinator derives from Roster; the host process
(bridge/host/process.py) relies on exactly this, plus `restore` and
`carriers` (docs/writing-a-behaviour.md, "What the host needs").
"""

from firmware_logic import messages as msg

SUBSET_SETUP = ("Roster",)    # host side: may allocate

BAD_HELLO = "hello out of range"
CHANGED_HELLO = "hello changes model or power"


class Roster:
    def __init__(self, models, journal_node=None, on_reject=None):
        """models: the movement model codes a HELLO may announce.
        journal_node: callable(node, model, power) for a newly announced node,
        called BEFORE its ACK (the host process makes it durable).
        on_reject: callable(reason, node, fields) for each refused report."""
        self.models = models
        self.journal_node = journal_node
        self.on_reject = on_reject
        self.nodes = {}          # node -> (model, power)
        self.acks = {}           # node -> seq of the one ACK it gets this tick
        self.rejected = {}       # reason -> count

    def _hello(self, node, f):
        model, power = f[0], f[1]
        known = self.nodes.get(node)
        if known is None:
            if model not in self.models or power < 1:
                self._reject(BAD_HELLO, node, f)
                return
            if self.journal_node is not None:
                self.journal_node(node, model, power)
            self.nodes[node] = (model, power)
        elif known != (model, power):
            # a robot's model and power do not change while it runs; taking
            # the new values would re-weigh its report, and the journal (which
            # holds the first HELLO) and memory would disagree after a resume
            self._reject(CHANGED_HELLO, node, f)
            return
        self._ack(node, 0)

    def _reject(self, reason, node=0, f=()):
        self.rejected[reason] = self.rejected.get(reason, 0) + 1
        if self.on_reject is not None:
            self.on_reject(reason, node, f)

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
