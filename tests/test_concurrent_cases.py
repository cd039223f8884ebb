"""The cases of a scenario run side by side (`vsj.scenario.run_cases`, which `vsj simulate`
and `vsj.scenario.run` use): each gives the bits it gives alone, in the cases' order, and
a failure stops the others and is raised as a run of one case after the other raises it.

The tests make the cases run two at a time whatever the machine's cores.
"""

import threading

import numpy as np
import pytest

from vsj import scenario as scenarios
from vsj.simulate import MemorySink, driver

#: How long a test's sink waits for another case before giving up (only a broken
#: run_cases makes it wait that long; the test then fails)
PATIENCE = 60.0


class Boom(Exception):
    """The failure a test's sink raises, naming its case."""


@pytest.fixture
def two_at_a_time(monkeypatch):
    monkeypatch.setattr(scenarios, "available_cores", lambda: 2)


@pytest.fixture(scope="module")
def prepared(params):
    scen = scenarios.load("fig-4.15")
    return [scenarios.prepare_case(scen, case, params) for case in scen.cases]


def test_cases_run_side_by_side_give_the_bits_they_give_alone(two_at_a_time, prepared):
    alone = [case.run() for case in prepared]
    together = scenarios.run_cases(prepared)
    assert len(together) == len(alone)
    # the cases differ (pivot positions): a mixed-up order or shared state shows
    assert not np.array_equal(alone[0]["theta_x"], alone[-1]["theta_x"])
    for one, other in zip(alone, together):
        assert (other.success, other.message, other.ledger) == \
            (one.success, one.message, one.ledger)
        assert list(other.signals) == list(one.signals)
        for name in one.signals:
            assert np.array_equal(other[name], one[name]), name


def test_the_first_failure_in_the_cases_order_is_raised(two_at_a_time, prepared):
    # case 2 fails first in time, while case 1 waits for it at its end and fails then:
    # one case after the other, case 1's failure is the one raised
    second_failed = threading.Event()

    class FailsAtEnd(MemorySink):
        def end(self, samples):
            second_failed.wait(PATIENCE)
            raise Boom("case 1")

    class FailsAtBegin(MemorySink):
        def begin(self, table, time):
            second_failed.set()
            raise Boom("case 2")

    sinks = [MemorySink() for _ in prepared]
    sinks[1], sinks[2] = FailsAtEnd(), FailsAtBegin()
    with pytest.raises(Boom, match="case 1"):
        scenarios.run_cases(prepared, sinks=sinks)


def test_a_failure_stops_the_other_runs_at_their_next_block(two_at_a_time, prepared,
                                                             monkeypatch):
    monkeypatch.setattr(driver, "BLOCK_BYTES", driver.BLOCK_BYTES // 64)  # blocks per run
    stop = threading.Event()
    writes = []

    class FailsAtBegin(MemorySink):
        def begin(self, table, time):
            raise Boom("case 0")

    class Waits(MemorySink):
        """Holds its run at the first block until the runs are told to stop."""

        def write(self, start, signals):
            writes.append(start)
            if len(writes) == 1:
                stop.wait(PATIENCE)
            super().write(start, signals)

    sinks = [FailsAtBegin(), Waits()] + [MemorySink() for _ in prepared[2:]]
    with pytest.raises(Boom, match="case 0"):
        scenarios.run_cases(prepared, sinks=sinks, stop=stop)
    assert stop.is_set()
    assert len(writes) <= 1, f"case 1 went on for {len(writes)} blocks after case 0 failed"
    assert not [t for t in threading.enumerate() if t.name.startswith("vsj-case")]


def test_runs_stop_when_the_caller_says(prepared):
    stop = threading.Event()
    stop.set()
    with pytest.raises(scenarios.Stopped):
        scenarios.run_cases(prepared[:2], stop=stop)
