"""Sweep progress moves per finished run, in this process and from worker
processes, and shows as plain lines when stderr is not a terminal."""

from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor

import pytest

from bridge.cli import main
from sim_backend import sweep

POINTS = sweep.grid_points({"fieldDefiance": [1, 4], "movementModel": ["firefly", "ant"]})
SEEDS = [1, 2, 3]


class FakeClock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def test_progress_log_lines_by_runs_and_by_time():
    lines: list[str] = []
    clock = FakeClock()
    log = sweep.ProgressLog(100, lines.append, every_runs=10, every_s=5.0, clock=clock)
    clock.t += 0.1
    log.update()                      # the first run always shows: the first result
    assert lines == ["sweep: 1/100 runs (1%), 10.00 runs/s, ETA 10s"]
    for _ in range(9):
        clock.t += 0.1
        log.update()
    assert len(lines) == 1
    clock.t += 0.1
    log.update()                      # 10 runs after the last line
    assert lines[-1] == "sweep: 11/100 runs (11%), 10.00 runs/s, ETA 9s"
    clock.t += 6.0                    # a slow run: the time limit shows it
    log.update()
    assert lines[-1] == "sweep: 12/100 runs (12%), 1.69 runs/s, ETA 52s"
    for _ in range(88):
        log.update()
    assert lines[-1].startswith("sweep: 100/100 runs (100%)")


def test_progress_log_of_a_resumed_sweep_counts_only_new_runs_in_the_rate():
    lines: list[str] = []
    clock = FakeClock()
    log = sweep.ProgressLog(10, lines.append, already=6, every_runs=1, clock=clock)
    clock.t = 2.0
    log.update()
    assert lines == ["sweep: 7/10 runs (70%), 0.50 runs/s, ETA 6s"]


@pytest.mark.parametrize("engine", ["soa", "reference"])
def test_progress_moves_per_run_inside_one_chunk(engine):
    """One chunk of 12 runs: progress comes as runs finish, not once at the end."""
    steps: list[int] = []
    rows = sweep.sweep(POINTS, SEEDS, overrides={"maxTicks": 3000}, engine=engine,
                       chunk_size=12, progress=steps.append)
    assert len({r["ticks"] for r in rows}) > 1      # the runs end at different ticks
    assert sum(steps) == 12
    assert len(steps) > 1 and all(s >= 1 for s in steps)


@pytest.mark.parametrize("pool", [ThreadPoolExecutor, ProcessPoolExecutor])
def test_progress_moves_per_run_from_workers(pool):
    steps: list[int] = []
    with pool(1) as ex:
        rows = sweep.sweep(POINTS, SEEDS, overrides={"maxTicks": 3000}, executor=ex,
                           chunk_size=12, progress=steps.append)
    assert len(rows) == 12 and sum(steps) == 12
    assert len(steps) > 1


def test_cli_prints_progress_lines_when_stderr_is_not_a_terminal(tmp_path, capsys):
    assert main(["sweep", "--grid", "fieldDefiance=1,4", "--grid", "movementModel=firefly,ant",
                 "--seeds", "3", "--set", "maxTicks=3000", "--executor", "inline",
                 "--chunk", "12", "--no-plots", "--out", str(tmp_path)]) == 0
    cap = capsys.readouterr()
    assert "12 runs (4 points x 3 seeds, soa (auto) engine, until delivered)" in cap.out
    lines = [ln for ln in cap.err.splitlines() if ln.startswith("sweep: ")]
    # one chunk of 12 runs, yet a line per finished run (every 5% of 12 runs is 1 run)
    assert len(lines) > 1
    assert lines[-1].startswith("sweep: 12/12 runs (100%)") and "runs/s, ETA" in lines[-1]


def test_worker_progress_channel_never_blocks_a_worker_and_keeps_order():
    """A worker's end (what pickling the inbox sends) puts without blocking,
    even when the sweep is not reading or has ended; the reader gets the
    counts in the order they were put, then Empty."""
    import pickle
    import queue
    with ProcessPoolExecutor(1) as pool:       # no work submitted: no process starts
        inbox, close = sweep._progress_queue(pool)
    out = pickle.loads(pickle.dumps(inbox))
    assert type(out) is not type(inbox)
    for k in range(1, 1001):           # far more than a socket holds unread
        out.put((7, k))
    got = []
    while True:
        try:
            got.append(inbox.get_nowait())
        except queue.Empty:
            break
    assert got and got == [(7, k) for k in range(1, len(got) + 1)]
    close()
    out.put((7, 1001))                 # the sweep has ended: dropped, no error
