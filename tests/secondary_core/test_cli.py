"""``atemr-secondary``: the standalone board on a virtual bus, with its terminal view and keys."""

from __future__ import annotations

import io
import threading

import can
import pytest

from atemr.io.can import CanId
from secondary_core.cli import TerminalView, build_parser, main
from secondary_core.harness import LinkBench, unique_channel


def test_runs_on_a_virtual_bus_and_shows_the_screen() -> None:
    channel = unique_channel("cli")
    listener = can.Bus(interface="virtual", channel=channel)
    out = io.StringIO()
    try:
        code = main(["--channel", channel, "--duration", "0.3", "--no-keys", "--no-portal", "--boot-s", "0.1"],
                    stdout=out)
        frames = []
        while (msg := listener.recv(timeout=0)) is not None:
            frames.append(msg.arbitration_id)
    finally:
        listener.shutdown()
    assert code == 0
    text = out.getvalue()
    assert "ATEMR secondary core on virtual:" in text and "SC CORE" in text and "Ready !!" in text
    assert CanId.IR_FRONT in frames and 0x141 in frames and 0x142 in frames  # IR and brake frames


def test_keys_drive_the_button_and_q_quits() -> None:
    channel = unique_channel("cli")
    keys = io.StringIO("1\nq\n")
    out = io.StringIO()
    done: list[int] = []
    thread = threading.Thread(target=lambda: done.append(main(
        ["--channel", channel, "--no-portal", "--view", "none", "--boot-s", "0", "--duration", "10"],
        stdin=keys, stdout=out)))
    thread.start()
    thread.join(timeout=15)
    assert done == [0], "q stops the board well before --duration"


def test_unknown_interface_is_a_clear_error(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--interface", "nosuchbus", "--channel", "x", "--no-keys"]) == 2
    assert "unknown CAN interface 'nosuchbus'" in capsys.readouterr().err


def test_bad_rate_refused(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--rate", "0", "--no-keys"]) == 2
    assert "--rate" in capsys.readouterr().err


def test_parser_defaults() -> None:
    args = build_parser().parse_args([])
    assert (args.interface, args.channel, args.portal_port, args.view) == ("virtual", "atemr", 5001, "text")


def test_terminal_view_redraws_only_on_change() -> None:
    with LinkBench() as bench:
        out = io.StringIO()
        view = TerminalView(bench.core, out=out, pixels=True, header="H")
        bench.run(0.1)
        view.tick(bench.now)
        first = out.getvalue()
        view.tick(bench.now)
        assert out.getvalue() == first and "█" in first and "SOFT EMERGENCY (starting up)" in first


def test_diagram_lists_every_transition() -> None:
    out = io.StringIO()
    assert main(["--diagram"], stdout=out) == 0
    text = out.getvalue()
    assert text.startswith("stateDiagram-v2")
    for edge in ("ready --> power_on: power_on_primary", "ops --> config: toggle", "config --> ops: portal_timeout",
                 "power_off --> shutdown: shutdown_due", "shutdown --> power_on_sequence: power_cycle"):
        assert edge in text
