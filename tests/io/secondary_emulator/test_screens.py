"""Screen contents in every board state (thesis figures 3.51–3.54), compared as text."""

from __future__ import annotations

import io
from collections.abc import Iterator

import pytest
from PIL import Image

from atemr.domain.status import AgentBits, HardwareBits, StateCode
from atemr.io.can import PrimaryStatus
from atemr.io.secondary_emulator.screens import SCREEN_NAMES, BoardView, build_screen
from atemr.msgs import CliffReadings
from secondary_core.harness import LinkBench


def box(*rows: str) -> str:
    border = "+" + "-" * 21 + "+"
    title, *body = rows
    return "\n".join([border, f"|{title}|", border, *(f"|{r}|" for r in body), border])


@pytest.fixture
def bench() -> Iterator[LinkBench]:
    with LinkBench(cliff=CliffReadings(0.0, 0.05, 0.05, 0.05)) as b:
        b.network.ip = "192.168.1.42"
        yield b


def test_every_state_has_a_screen() -> None:
    for state in SCREEN_NAMES:
        assert build_screen(BoardView(state=state)).title
    with pytest.raises(KeyError):
        build_screen(BoardView(state="nonsense"))


def test_screens_through_a_whole_session(bench: LinkBench) -> None:
    bench.run(1.5)
    assert bench.core.screen_name == "POWER-ON SEQUENCE"
    assert bench.core.screen_text() == box(
        "     ATEMR - KAY     ",
        "Telepresence robot   ",
        "by E.-E. G. Asare    ",
        "Loading, wait...     ",
        "[##########.........]",
    )
    bench.run(2.0)
    assert bench.core.screen_name == "BOOT/READY"
    assert bench.core.screen_text() == box(
        "       SC CORE       ",
        "                     ",
        " (@)   Ready !!      ",
        "                     ",
        "       hold 1s: on   ",
    )
    bench.core.button.hold(1.0)
    bench.run(4.0)
    assert bench.core.screen_name == "POWER-ON"
    assert bench.core.screen_text() == box(
        "       POWER ON      ",
        "Input received.      ",
        "Powering on the      ",
        "primary core...      ",
        "[##.................]",
    )
    bench.link.set_power_state(1)
    bench.link.set_status(AgentBits.HEARTBEAT | AgentBits.HARDWARE | AgentBits.CONNECTIVITY,
                          HardwareBits(0xFF) & ~HardwareBits.CAMERA, StateCode.IDLE)
    bench.run(1.0)
    assert bench.core.screen_name == "OPS"
    assert bench.core.screen_text() == box(
        "         IDLE        ",
        "AGENT 00001011       ",
        "HDW   11101111       ",
        "MANUAL HB OK         ",
        "IP 0.0.0.0           ",
    )
    bench.core.button.short_press()
    bench.run(10.0)
    assert bench.core.screen_name == "CONFIG"
    assert bench.core.screen_text() == box(
        "    PORTAL ON 111s   ",  # the press lands at the next tick: 110.02 s left, rounded up
        "IP 192.168.1.42      ",
        "AP ATEMR-Connect     ",
        "PW 123456789         ",
        "http://192.168.4.1   ",
    )
    bench.core.button.hold(5.0)
    bench.run(5.5)
    assert bench.core.screen_name == "POWER-OFF"
    assert bench.core.screen_text() == box(
        "      POWER OFF      ",
        "Power-off request    ",
        "sent. Waiting for    ",
        "the primary core...  ",
        "                     ",
    )
    bench.link.acknowledge_power_off()
    bench.run(2.0)
    assert bench.core.screen_text() == box(
        "      POWER OFF      ",
        "Acknowledged.        ",
        "Primary core is      ",
        "shutting down.       ",
        "Wait 4s...           ",
    )
    bench.run(4.0)
    assert bench.core.screen_name == "SHUTDOWN"
    assert bench.core.screen_text() == box(
        "       SHUTDOWN      ",
        "Primary core off.    ",
        "                     ",
        "Turn the power       ",
        "switch OFF now.      ",
    )
    with Image.open(io.BytesIO(bench.core.screen_png())) as img:
        assert img.size == (128, 64)


@pytest.mark.parametrize("state", list(StateCode))
def test_ops_title_is_the_state_name(state: StateCode) -> None:
    view = BoardView(state="ops", status=PrimaryStatus(AgentBits.AUTO, HardwareBits.NONE, state), heartbeat_ok=True)
    screen = build_screen(view)
    assert screen.title == state.name and "AUTO" in screen.lines[2]


def test_ops_shows_why_the_motors_are_braked() -> None:
    screen = build_screen(BoardView(state="ops", emergency_reason="primary not running"))
    assert screen.lines[3] == "BRAKE primary down" and "HB LOST" in screen.lines[2]


def test_config_without_portal_says_off() -> None:
    assert build_screen(BoardView(state="config", portal_left_s=None)).title == "PORTAL OFF"


def test_snapshot_for_the_dashboard(bench: LinkBench) -> None:
    bench.bring_up()
    snap = bench.core.snapshot()
    assert snap["state"] == "ops" and snap["screen"] == "OPS" and snap["heartbeat_ok"] is True
    assert snap["soft_emergency"] is False and "AGENT" in snap["screen_text"] and snap["events"]
