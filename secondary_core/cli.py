"""``atemr-secondary``: the emulated secondary core on its own, on any python-can bus, with a terminal view.

    atemr-secondary --interface virtual --channel atemr       # beside a simulated primary
    atemr-secondary --interface socketcan --channel can0      # in place of the real board

The board runs on the wall clock; the terminal shows its display (as text, or as pixels with
``--view pixels``) and its latest events. Keys (type a letter, then Enter): ``s`` short press, ``1`` hold
1 s, ``5`` hold 5 s, ``r`` power-cycle the board, ``q`` quit. The captive portal is served on
``--portal-host``:``--portal-port`` while the board is in CONFIG.
"""

from __future__ import annotations

import argparse
import logging
import math
import signal
import sys
import threading
from collections.abc import Sequence
from types import FrameType
from typing import TextIO

from atemr.clock import WallClock
from atemr.config import CanConfig
from atemr.errors import AtemrError, HardwareError
from atemr.io.can.bus import open_bus
from atemr.io.secondary_emulator.board import BoardConfig, SecondaryCore, mermaid_diagram
from atemr.io.secondary_emulator.display import render_pixels, render_text
from atemr.io.secondary_emulator.portal import DEFAULT_PORT, PortalHost
from atemr.msgs import CliffReadings
from atemr.scheduler import Scheduler

log = logging.getLogger(__name__)

KEYS = "s = short press · 1 = hold 1 s · 5 = hold 5 s · r = power-cycle · q = quit (then Enter)"


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="atemr-secondary",
        description="Emulated ATEMR secondary core (ESP32 board) on a python-can bus, with a terminal view.",
    )
    parser.add_argument("--interface", default="virtual", help="python-can interface (default: virtual)")
    parser.add_argument("--channel", default="atemr", help="bus channel (default: atemr; can0 on the robot)")
    parser.add_argument("--bitrate", type=int, default=1_000_000, help="bit rate of real interfaces (1 Mbit/s)")
    parser.add_argument("--rate", type=float, default=50.0, help="board tick rate in Hz (default 50)")
    parser.add_argument("--boot-s", type=float, default=BoardConfig.boot_s, help="length of the power-on sequence")
    parser.add_argument("--name", default=BoardConfig.robot_name, help="robot name on the screens")
    parser.add_argument("--portal-host", default="127.0.0.1", help="captive portal address (0.0.0.0: all)")
    parser.add_argument("--portal-port", type=int, default=DEFAULT_PORT, help=f"captive portal port ({DEFAULT_PORT})")
    parser.add_argument("--no-portal", action="store_true", help="do not serve the captive portal")
    parser.add_argument(
        "--ir-cm", type=float, nargs=3, metavar=("LEFT", "RIGHT", "REAR"), default=(5.0, 5.0, 5.0),
        help="fixed floor distances the IR sensors report, cm (default 5 5 5)",
    )
    parser.add_argument("--no-ir", action="store_true", help="do not publish IR frames")
    parser.add_argument("--view", choices=["text", "pixels", "none"], default="text", help="terminal view")
    parser.add_argument("--no-keys", action="store_true", help="do not read keys from standard input")
    parser.add_argument("--diagram", action="store_true", help="print the board's state machine (Mermaid) and exit")
    parser.add_argument("--duration", type=float, help="stop after this many seconds (default: until q or Ctrl-C)")
    parser.add_argument("--log-level", default="WARNING", type=str.upper,
                        choices=["DEBUG", "INFO", "WARNING", "ERROR", "CRITICAL"])
    return parser


class TerminalView:
    """Redraws the board's display and latest events when they change (a scheduler component, ~5 Hz)."""

    def __init__(self, core: SecondaryCore, *, out: TextIO, pixels: bool = False, header: str = "",
                 name: str = "secondary_view") -> None:
        self.name = name
        self.core = core
        self.out = out
        self.pixels = pixels
        self.header = header
        self._last = ""
        self._clear = out.isatty()

    def render(self) -> str:
        core = self.core
        screen = core.screen()
        body = render_pixels(screen) if self.pixels else render_text(screen)
        flags = [f"screen {core.screen_name}", "HB ok" if core.heartbeat_ok else "HB --"]
        if core.soft_emergency:
            flags.append(f"SOFT EMERGENCY ({core.emergency_reason})")
        if core.portal_active:
            flags.append(f"portal {int(core.portal_left_s or 0)} s")
        events = [str(e) for e in core.events.recent(6)]
        return "\n".join([self.header, body, " · ".join(flags), *events])

    def tick(self, now: float) -> None:
        text = self.render()
        if text == self._last:
            return
        self._last = text
        if self._clear:
            self.out.write("\x1b[2J\x1b[H")
        self.out.write(text + "\n\n")
        self.out.flush()


class _QuitWatcher:
    """Stops the scheduler from inside a tick once ``quit`` is set (a stop asked before `Scheduler.run`
    started would be lost, since run clears it)."""

    name = "secondary_quit"

    def __init__(self, scheduler: Scheduler, quit_event: threading.Event) -> None:
        self.scheduler = scheduler
        self.quit = quit_event

    def tick(self, now: float) -> None:
        if self.quit.is_set():
            self.scheduler.stop()


def _read_keys(core: SecondaryCore, quit_event: threading.Event, stream: TextIO) -> None:
    """Turn typed letters into button presses (runs in a daemon thread: input is an edge of the system)."""
    for line in stream:
        key = line.strip().lower()
        if key == "s":
            core.button.short_press()
        elif key == "1":
            core.button.hold(1.0)
        elif key == "5":
            core.button.hold(5.0)
        elif key == "r":
            core.reboot()
        elif key == "q":
            break
    quit_event.set()


def main(argv: Sequence[str] | None = None, *, stdin: TextIO | None = None, stdout: TextIO | None = None) -> int:
    """Entry point of ``atemr-secondary``; returns the exit code (2 for a bus or configuration error)."""
    args = build_parser().parse_args(argv)
    out = stdout or sys.stdout
    if args.diagram:
        out.write(mermaid_diagram() + "\n")
        return 0
    logging.basicConfig(level=args.log_level, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    try:
        if not (math.isfinite(args.rate) and args.rate > 0):
            raise HardwareError(f"--rate must be > 0 Hz, got {args.rate}", component="secondary core")
        config = BoardConfig(robot_name=args.name, boot_s=args.boot_s)
        bus = open_bus(CanConfig(interface=args.interface, channel=args.channel, bitrate=args.bitrate))
    except AtemrError as exc:
        print(f"atemr-secondary: error: {exc}", file=sys.stderr)
        return 2
    clock = WallClock()
    left_cm, right_cm, rear_cm = args.ir_cm
    cliff = None if args.no_ir else (
        lambda: CliffReadings(clock.now(), left_cm / 100.0, right_cm / 100.0, rear_cm / 100.0)
    )
    core = SecondaryCore(bus, cliff_source=cliff, config=config)
    scheduler = Scheduler(clock)
    scheduler.add(core, args.rate)
    if not args.no_portal:
        scheduler.add(PortalHost(core, host=args.portal_host, port=args.portal_port), 5.0)
    if args.view != "none":
        header = f"ATEMR secondary core on {args.interface}:{args.channel}" + ("" if args.no_keys else f"\n{KEYS}")
        scheduler.add(TerminalView(core, out=out, pixels=args.view == "pixels", header=header), 5.0)
    quit_event = threading.Event()
    scheduler.add(_QuitWatcher(scheduler, quit_event), 10.0)
    if not args.no_keys:
        threading.Thread(target=_read_keys, args=(core, quit_event, stdin or sys.stdin), daemon=True,
                         name="secondary-keys").start()

    def on_signal(signum: int, frame: FrameType | None) -> None:
        quit_event.set()
        scheduler.stop()

    in_main_thread = threading.current_thread() is threading.main_thread()
    previous = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)} if in_main_thread else {}
    try:
        scheduler.start()
        scheduler.run(duration=args.duration)
    finally:
        scheduler.shutdown()
        bus.shutdown()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    return 0


if __name__ == "__main__":
    sys.exit(main())
