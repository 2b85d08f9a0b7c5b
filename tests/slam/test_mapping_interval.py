"""slam.mapping_interval_s has one home (slam/mapping_interval.py): the reader's skip before
decoding and the replay's skip keep the same sweeps, also after an empty sweep."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from mrnc_eval.slam.mapping_interval import MappingInterval

STAMPS = [0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8]  # a 10 Hz sensor
EMPTY = {0.2}  # a sweep with no valid return


def _replay_maps(stamps: list[float], taken: Callable[[float, bool], bool]) -> list[float]:
    """Stamps the replay maps: its rule says yes and the sweep has points."""
    return [t for t in stamps if taken(t, t in EMPTY) and t not in EMPTY]


def _one_rule(interval: float) -> Callable[[float, bool], bool]:
    rule = MappingInterval(interval_s=interval)
    return lambda t, _empty: rule.take(t)


def _two_rules(interval: float) -> Callable[[float, bool], bool]:
    """The replay's rule before issue 24: the slot counted from the last sweep *mapped*."""
    last = [float("-inf")]

    def taken(t: float, empty: bool) -> bool:
        if t - last[0] < interval:
            return False
        if not empty:
            last[0] = t
        return True

    return taken


@pytest.mark.parametrize("interval", [0.0, 0.15, 0.25])
def test_the_reader_and_the_replay_keep_the_same_sweeps(interval: float) -> None:
    reader = MappingInterval(interval_s=interval)
    prefiltered = [t for t in STAMPS if reader.take(t)]  # skipped before decoding, in the reader's thread
    assert _replay_maps(prefiltered, _one_rule(interval)) == _replay_maps(STAMPS, _one_rule(interval))


def test_the_rule_takes_every_other_sweep_of_a_10_hz_sensor_at_0_15_s() -> None:
    rule = MappingInterval(interval_s=0.15)
    assert [t for t in STAMPS if rule.take(t)] == [0.0, 0.2, 0.4, 0.6, 0.8]


def test_two_homes_disagreed_after_an_empty_sweep() -> None:
    """Negative control: the reader's skip with the replay's old rule maps another set of sweeps
    than the old rule alone (0.3 is mapped only without the reader's skip)."""
    reader = MappingInterval(interval_s=0.15)
    prefiltered = [t for t in STAMPS if reader.take(t)]
    assert _replay_maps(prefiltered, _two_rules(0.15)) != _replay_maps(STAMPS, _two_rules(0.15))
