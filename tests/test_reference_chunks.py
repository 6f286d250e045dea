"""How a cold-cache sweep splits its reference runs among workers while the
soa step compiles (sweep._Engines.chunk_size): the chunks shrink towards the
end so that the workers end together; one worker keeps whole chunks."""

from sim_backend import sweep


class Compiling:
    pid = 1
    error = None
    seconds = None

    def finished(self) -> bool:
        return False


def chunks(runs: int, workers: int, chunk_size: int = 256) -> list[int]:
    plan = sweep._Engines("auto", Compiling())
    out, left = [], runs
    while left:
        eng = plan.poll()
        n = min(left, plan.chunk_size(eng, chunk_size, left, workers))
        out.append(n)
        left -= n
    return out


def test_two_workers_end_together_on_a_20_seed_sweep():
    got = chunks(20, 2)
    assert got == [4, 4, 3, 2, 1, 1, 1, 1, 1, 1, 1]
    assert max(got) == sweep.REFERENCE_CHUNK


def test_one_worker_keeps_whole_chunks():
    assert chunks(10, 1) == [4, 4, 2]


def test_a_chunk_size_asked_for_is_an_upper_bound():
    assert chunks(20, 2, chunk_size=2) == [2] * 7 + [1] * 6


def test_without_a_compile_the_chunk_size_is_the_sweeps():
    plan = sweep._Engines("reference")
    assert plan.chunk_size(plan.poll(), 256, 20, 2) == 256
