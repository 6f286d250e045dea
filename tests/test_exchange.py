"""sim_backend/exchange.py, the host's side of a tick boundary both engines
follow, on a stand-in coordinator: messages in the order sent but the
muted ones, a tick when heard or asked, a declaration kept while unchanged."""

from sim_backend.exchange import HEARS_ALL, NEVER, exchange, muting, quiet, wake


class Host:
    def __init__(self, muted=None, quiet=None):
        self.heard = []
        self.ticks = []
        self.nodes = {1, 2, 3}
        if muted is not None:
            self.muted = muted
        if quiet is not None:
            self.quiet = quiet

    def on_message(self, node, kind, f, t):
        self.heard.append((node, kind, f, t))

    def tick(self, t):
        self.ticks.append(t)
        return [(0, 9, (t,))]


UP = [(2, 5, (1,)), (1, 4, ()), (3, 5, (2,)), (4, 5, (3,))]


def test_without_muted_every_message_in_order_then_a_tick():
    c = Host()
    assert exchange(c, UP, 7) == [(0, 9, (7,))]
    assert c.heard == [(n, k, f, 7) for n, k, f in UP] and c.ticks == [7]
    assert muting(c) is HEARS_ALL and not quiet(c)


def test_muted_kind_from_the_nodes_but_one_is_dropped():
    c = Host()
    c.muted = lambda: (5, c.nodes, 3)
    exchange(c, UP, 2)
    assert [m[0] for m in c.heard] == [1, 3, 4]      # node 2's kind 5 dropped


def test_not_asked_and_nothing_heard_means_no_tick():
    c = Host(muted=lambda: (5, {2, 3, 4}, 0), quiet=lambda: True)
    assert exchange(c, [m for m in UP if m[1] == 5], 3, asked=False) is None
    assert c.heard == [] and c.ticks == [] and quiet(c)
    assert exchange(c, UP, 4, asked=False) == [(0, 9, (4,))]   # node 1's kind 4 heard


def test_a_declaration_is_kept_until_it_changes():
    c = Host()
    c.muted = lambda: (5, c.nodes, 0)
    first = muting(c)
    assert muting(c, first) is first
    c.nodes.add(4)                                    # the collection grew
    grown = muting(c, first)
    assert grown is not first and 4 in grown.drop


def test_the_declaration_is_read_before_the_messages():
    """A node the coordinator takes in while hearing this tick's messages
    is not muted until its next tick (muted() holds from one tick() on)."""
    c = Host()
    c.nodes = {1}
    c.muted = lambda: (5, c.nodes, 0)
    hear = c.on_message

    def announcing(node, kind, f, t):
        c.nodes.add(node)
        hear(node, kind, f, t)
    c.on_message = announcing
    exchange(c, [(2, 4, ()), (2, 5, ()), (1, 5, ())], 1)
    assert [m[:2] for m in c.heard] == [(2, 4), (2, 5)]


def test_a_batch_drops_in_bulk_what_each_run_muted_and_follows_a_change():
    """BatchMutes: run 0 (robots 0-3, nodes 1-4) mutes kind 5 but from its
    node 3, run 1 (robots 4-5) hears all; the same messages exchange would
    drop, and a grown declaration is picked up by update()."""
    import numpy as np
    from sim_backend.exchange import BatchMutes
    a, b = Host(), Host()
    a.nodes = {1, 2, 3}
    a.muted = lambda: (5, a.nodes, 3)
    mutes = BatchMutes([a, b], [0, 4], [4, 2], np.array([0, 0, 0, 0, 1, 1]))
    robot = np.array([0, 1, 2, 3, 0, 4, 5])
    kind = np.array([5, 5, 5, 5, 4, 5, 5])
    fields = np.zeros((len(robot), 2), dtype=np.int64)
    assert mutes.keep(robot, kind, fields).tolist() == [False, False, True, True, True, True, True]
    a.nodes.add(4)
    mutes.update(0, a)
    assert mutes.keep(robot, kind, fields).tolist() == [False, False, True, False, True, True,
                                                        True]


def test_a_repeat_of_the_declared_fields_is_dropped_until_other_fields_come():
    """muted()'s fourth member: node 3's kind-5 message with fields (7,) is
    dropped; one with other fields is handed over and ends the clause, so
    the repeat after it is handed over too (it may change something now)."""
    c = Host()
    c.muted = lambda: (5, {1, 2}, 3, (7,))
    up = [(3, 5, (7,)), (3, 5, (7,)), (3, 4, (7,)), (3, 5, (8,)), (3, 5, (7,))]
    exchange(c, up, 1)
    assert [(m[1], m[2]) for m in c.heard] == [(4, (7,)), (5, (8,)), (5, (7,))]
    exchange(c, up[:1], 2)                            # read again at the next exchange
    assert len(c.heard) == 3
    m = muting(c)
    assert muting(c, m) is m and not m.drops(3, 5, (8,))     # (8,) ends the clause ...
    again = muting(c, m)                                      # ... until it is read again
    assert again is not m and again.drops(3, 5, (7,)) and not m.drops(3, 5, (7,))


def test_the_bulk_rule_is_the_one_by_one_rule():
    """BatchMutes.keep drops exactly what Muting.drops drops, message by
    message in the order sent, over random declarations with and without a
    repeat clause (two runs, a sender sending twice in one tick)."""
    import random
    import numpy as np
    from sim_backend.exchange import BatchMutes
    rng = random.Random(5)
    for _ in range(200):
        hosts, decl = [Host(), Host()], []
        for h in hosts:
            d = rng.choice([None, (5, {1, 2}, 3), (5, {1, 2, 3}, 3, (rng.randrange(2),)),
                            (4, {2}, 1, (1,))])
            decl.append(d)
            h.muted = (lambda d=d: d)
        mutes = BatchMutes(hosts, [0, 3], [3, 3], np.array([0, 0, 0, 1, 1, 1]))
        n = rng.randrange(1, 9)
        robot = np.array([rng.randrange(6) for _ in range(n)])
        kind = np.array([rng.choice((4, 5)) for _ in range(n)])
        fields = np.array([[rng.randrange(2), 9] for _ in range(n)])
        one = [muting(h) for h in hosts]
        want = [not one[r // 3].drops(r % 3 + 1, k, (f[0],))
                for r, k, f in zip(robot.tolist(), kind.tolist(), fields.tolist())]
        assert mutes.keep(robot, kind, fields).tolist() == want, (decl, robot, kind, fields)


def test_wake_is_never_while_quiet_else_idle_until():
    c = Host()
    assert wake(c) == 0                               # asked every tick
    c.idle_until = lambda: 12
    assert wake(c) == 12
    c.quiet = lambda: True
    assert wake(c) == NEVER
