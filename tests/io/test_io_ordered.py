"""OrderedPool: results in submission order whatever the threads, turns in submission order,
errors raised unchanged on the collecting thread, bounded in-flight calls, clean close."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from roslan.io.ordered import OrderedPool, Turn


def _run(pool: OrderedPool[int], n: int, fn: object) -> list[int]:
    out: list[int] = []
    try:
        for i in range(n):
            out += pool.submit(fn, i)
        out += pool.finish()
    finally:
        pool.close()
    return out


def test_results_come_back_in_submission_order_from_other_threads() -> None:
    names: set[str] = set()
    # later calls finish first: a pool that handed back results as they complete would
    # return them reversed within each window
    delays = np.random.default_rng(1).uniform(0.0, 0.004, 60)

    def work(turn: Turn, i: int) -> int:
        time.sleep(float(delays[i]))
        names.add(threading.current_thread().name)
        return i * i

    got = _run(OrderedPool(3, "ord"), 60, work)
    assert got == [i * i for i in range(60)]
    assert all(n.startswith("ord") for n in names)
    assert len(names) > 1  # really spread over threads


def test_one_thread_runs_every_call_inline() -> None:
    main = threading.current_thread().name
    seen: list[str] = []

    def work(turn: Turn, i: int) -> int:
        seen.append(threading.current_thread().name)
        return i

    pool: OrderedPool[int] = OrderedPool(1, "x")
    assert pool.inline
    assert pool.submit(work, 7) == [7]  # done before submit returns
    assert seen == [main]
    pool.close()


@pytest.mark.parametrize("threads", [1, 2, 4])
def test_turns_draw_one_generator_in_submission_order(threads: int) -> None:
    """Poisson draws (their count of underlying random numbers depends on the data)
    inside the turn give the inline stream, bit for bit, whatever the threads."""
    lam = [np.full(50, 0.5 + 3 * i, dtype=np.float64) for i in range(24)]
    ref_rng = np.random.default_rng(5)
    expected = [ref_rng.poisson(x) for x in lam]
    rng = np.random.default_rng(5)
    delays = np.random.default_rng(2).uniform(0.0, 0.003, 24)

    def work(turn: Turn, i: int) -> np.ndarray:
        time.sleep(float(delays[i]))  # work before the draw, of varying length
        with turn:
            x = rng.poisson(lam[i])
        time.sleep(float(delays[-1 - i]))  # and after it
        return x

    pool: OrderedPool[np.ndarray] = OrderedPool(threads, "t")
    got: list[np.ndarray] = []
    for i in range(24):
        got += pool.submit(work, i)
    got += pool.finish()
    pool.close()
    assert len(got) == 24
    for a, b in zip(got, expected, strict=True):
        np.testing.assert_array_equal(a, b)


def test_a_call_without_its_turn_does_not_block_the_next_turn() -> None:
    order: list[int] = []

    def work(turn: Turn, i: int) -> int:
        if i % 2:
            with turn:
                order.append(i)
        return i

    assert _run(OrderedPool(3, "t"), 10, work) == list(range(10))
    assert order == [1, 3, 5, 7, 9]


def test_a_turn_is_entered_once() -> None:
    def work(turn: Turn, i: int) -> int:
        with turn:
            pass
        with turn:
            pass
        return i

    pool: OrderedPool[int] = OrderedPool(1, "t")
    with pytest.raises(RuntimeError, match="entered once"):
        pool.submit(work, 0)
    pool.close()


@pytest.mark.parametrize("threads", [1, 3])
def test_an_error_comes_back_unchanged_when_its_result_is_due(threads: int) -> None:
    class DiskFullError(OSError):
        pass

    def work(turn: Turn, i: int) -> int:
        if i == 4:
            msg = "images/00000004.png: disk full"
            raise DiskFullError(msg)
        with turn:
            return i

    pool: OrderedPool[int] = OrderedPool(threads, "t")
    got: list[int] = []

    def collect() -> None:
        for i in range(20):
            got.extend(pool.submit(work, i))
        got.extend(pool.finish())

    with pytest.raises(DiskFullError, match=r"^images/00000004\.png: disk full$"):
        collect()
    pool.close()
    assert got == [0, 1, 2, 3][: len(got)]  # the results before it, in order


def test_in_flight_calls_are_bounded_by_depth() -> None:
    def work(turn: Turn, i: int) -> int:
        time.sleep(0.002)
        return i

    pool: OrderedPool[int] = OrderedPool(2, "t", depth=3)
    held: list[int] = []
    for i in range(40):
        held += pool.submit(work, i)
        # a submit returns with at most depth - 1 calls not handed back: the next one
        # makes depth, never more
        assert len(pool._pending) <= 2
        assert len(held) >= i - 1
    held += pool.finish()
    pool.close()
    assert held == list(range(40))


def test_close_drops_waiting_calls_and_wakes_those_waiting_for_their_turn() -> None:
    started = threading.Event()
    release = threading.Event()
    ran: list[int] = []

    def work(turn: Turn, i: int) -> int:
        if i == 0:
            started.set()
            release.wait(5)  # holds its turn: call 1 waits for it
        with turn:
            ran.append(i)
        return i

    pool: OrderedPool[int] = OrderedPool(2, "t", depth=8)
    for i in range(6):
        pool.submit(work, i)
    assert started.wait(5)
    t = threading.Thread(target=pool.close)
    t.start()
    time.sleep(0.05)
    release.set()
    t.join(5)
    assert not t.is_alive()
    # call 0 (already in its turn's queue position) finishes; call 1, woken by the close
    # while it waited for its turn, and the calls not started never run their turn
    assert ran == [0]
    with pytest.raises(RuntimeError, match="closed"):
        pool.submit(work, 9)
    pool.close()  # idempotent


def test_on_a_shared_executor_close_stops_only_this_pools_calls() -> None:
    """On a shared executor (the bags' chunk pool) results still come back in order; close
    drops this pool's calls not started, waits for its running one, and leaves the
    executor running for its other users."""
    from concurrent.futures import ThreadPoolExecutor

    release = threading.Event()
    started = threading.Event()
    ran: list[int] = []

    def work(turn: Turn, i: int) -> int:
        if i == 0:
            started.set()
            release.wait(5)
        time.sleep(0.001 * (5 - i % 5))  # later calls finish first
        ran.append(i)
        return i

    with ThreadPoolExecutor(1) as shared:
        pool: OrderedPool[int] = OrderedPool(1, "t", depth=4, executor=shared)
        assert not pool.inline
        release.set()
        assert _run(pool, 12, work) == list(range(12))
        release.clear()
        started.clear()
        stopped: OrderedPool[int] = OrderedPool(1, "t", depth=8, executor=shared)
        for i in range(5):
            stopped.submit(work, i)  # call 0 holds the executor's one thread
        assert stopped.in_flight == 5
        assert started.wait(5)
        closer = threading.Thread(target=stopped.close)
        closer.start()
        time.sleep(0.05)
        assert closer.is_alive()  # it waits for the running call
        release.set()
        closer.join(5)
        assert not closer.is_alive()
        assert ran[12:] == [0]  # calls 1-4 never started
        assert stopped.in_flight == 0
        assert shared.submit(lambda: 7).result(5) == 7  # the executor still runs
