"""A serial device on a pseudo-terminal that can be unplugged and plugged in again: the emulators' port.

`PluggablePty` keeps one stable path, ``port``: a symlink in a directory (a temporary one it makes, or one
it is given) to the device side of a pty. `plug` opens a new pty (device side in raw mode, the emulator's
side non-blocking) and re-points the link at it atomically, so a host never sees a half-made link;
`unplug` closes the pty (a host's reads fail) and removes the link, as when a USB adapter leaves and comes
back at the same udev name; `close` unplugs and removes the directory if it made it.

An emulator reads and writes the current pty's `master` while holding `lock` (`unplug` closes it under the
same lock); the lock is the emulator's too, for the device state it keeps beside the pty.

`PtyEmulator` is the emulators' common life cycle on top: a daemon thread that plays the device, the
``port``, ``plugged``, ``unplug``, ``replug`` and ``close`` every emulator offers, and use as a context
manager.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
import threading
import tty
from abc import ABC, abstractmethod
from collections.abc import Callable
from pathlib import Path
from types import TracebackType
from typing import Self


class _Pty:
    """One plugged-in device: both ends of a pty, kept open so that its raw settings stay while no host has
    it open. The host opens the slave (through the link); the emulator uses the non-blocking master."""

    def __init__(self) -> None:
        self.master, self.slave = os.openpty()
        try:
            tty.setraw(self.slave)
            os.set_blocking(self.master, False)
            self.path = os.ttyname(self.slave)
        except BaseException:
            self.close()
            raise

    def close(self) -> None:
        for fd in (self.master, self.slave):
            with contextlib.suppress(OSError):
                os.close(fd)


class PluggablePty:
    """A stable ``port`` path to whichever pty is plugged in now (see the module docstring).

    ``directory`` is where the link ``link_name`` lives; None makes a temporary directory (its name starts
    with ``prefix``) that `close` removes. Nothing is plugged in until `plug`.
    """

    def __init__(self, link_name: str, *, directory: str | Path | None = None, prefix: str = "atemr-pty-") -> None:
        self._own_directory = directory is None
        self.directory = Path(tempfile.mkdtemp(prefix=prefix) if directory is None else directory)
        #: The path a host opens (a symlink to the current pty's device side; absent while unplugged).
        self.port = str(self.directory / link_name)
        #: Held while the current pty is used, swapped or closed.
        self.lock = threading.Lock()
        self._pty: _Pty | None = None

    @property
    def plugged(self) -> bool:
        return self._pty is not None

    @property
    def master(self) -> int | None:
        """The current pty's (non-blocking) master file descriptor, None while unplugged; read it and use it
        holding `lock`, so that `unplug` cannot close it meanwhile."""
        pty = self._pty
        return None if pty is None else pty.master

    def plug(self, on_plug: Callable[[], None] | None = None) -> None:
        """Plug in a new pty (unplugging the current one first) and point ``port`` at it atomically.
        ``on_plug`` (the device powering on) runs holding `lock`, just before the new pty becomes `master`."""
        self.unplug()
        pty = _Pty()
        link = Path(self.port)
        tmp = link.with_name(f".{link.name}.new")
        try:
            tmp.unlink(missing_ok=True)
            tmp.symlink_to(pty.path)
            os.replace(tmp, link)  # atomic: a host never sees a half-made link
        except BaseException:
            pty.close()
            raise
        with self.lock:
            try:
                if on_plug is not None:
                    on_plug()
            except BaseException:
                link.unlink(missing_ok=True)
                pty.close()
                raise
            self._pty = pty

    def unplug(self) -> None:
        """Pull the device: its pty closes (a host's reads fail) and ``port`` disappears; idempotent."""
        with self.lock:
            pty, self._pty = self._pty, None
            Path(self.port).unlink(missing_ok=True)
            if pty is not None:
                pty.close()

    def close(self) -> None:
        """Unplug, and remove the directory if this made it; idempotent."""
        self.unplug()
        if self._own_directory:
            shutil.rmtree(self.directory, ignore_errors=True)


class PtyEmulator(ABC):
    """A serial device played on a `PluggablePty` by a daemon thread of its own (see the module docstring).

    Subclasses implement `start` (plug in if need be, then `_start_thread`), `_power_on` (the device's state
    as just switched on; it runs holding ``_lock`` at every plug) and `_run` (the thread's loop, until
    ``_stop`` is set; it uses ``_pty.master`` holding ``_lock``, which also guards the device's state).
    """

    def __init__(self, link_name: str, *, directory: str | Path | None, prefix: str) -> None:
        self._pty = PluggablePty(link_name, directory=directory, prefix=prefix)
        self._lock = self._pty.lock
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    @abstractmethod
    def start(self) -> object:
        """Start playing the device."""

    @abstractmethod
    def _power_on(self) -> None:
        """Reset the device's state as at power-on."""

    @abstractmethod
    def _run(self) -> None:
        """The thread: play the device until ``_stop`` is set."""

    @property
    def port(self) -> str:
        """The stable path a host opens (a symlink to the current pty)."""
        return self._pty.port

    @property
    def plugged(self) -> bool:
        return self._pty.plugged

    def unplug(self) -> None:
        """The USB adapter is pulled: the pty closes (the host's reads fail) and ``port`` disappears."""
        self._pty.unplug()

    def replug(self) -> None:
        """The adapter comes back (unplugged first if it was in): a device just powered on, on a new pty, with
        ``port`` re-pointed to it atomically."""
        self._pty.plug(on_plug=self._power_on)

    def close(self) -> None:
        """Stop the thread, unplug, and remove the temporary directory if the emulator made it; idempotent."""
        self._stop.set()
        thread, self._thread = self._thread, None
        if thread is not None:
            thread.join(timeout=2.0)
        self._pty.close()

    def _start_thread(self, name: str) -> None:
        """Start the thread that plays the device (idempotent)."""
        if self._thread is not None:
            return
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    def __enter__(self) -> Self:
        self.start()
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()
