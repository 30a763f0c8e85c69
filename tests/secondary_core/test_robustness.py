"""Random frames on every inter-core ID never crash either end of the link (hypothesis)."""

from __future__ import annotations

import can
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from secondary_core.harness import LinkBench

frames = st.lists(
    st.tuples(st.integers(min_value=0x140, max_value=0x158), st.binary(max_size=8), st.booleans()),
    max_size=30,
)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(frames)
def test_random_frames_never_crash_board_or_link(junk: list[tuple[int, bytes, bool]]) -> None:
    with LinkBench() as bench:
        bench.bring_up()
        for arbitration_id, data, remote in junk:
            bench.spy.send(can.Message(arbitration_id=arbitration_id, data=data, is_extended_id=False,
                                       is_remote_frame=remote and not data, check=False))
        bench.run(0.2)  # neither tick raises
        assert bench.core.state in ("ops", "config", "power_off")
        snapshot = bench.core.snapshot()
        assert snapshot["screen_text"].count("\n") == 7
        assert bench.link.diagnostics()["frames_in"] >= 0
