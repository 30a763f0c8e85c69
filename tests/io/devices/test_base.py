"""The device layer's shared pieces: `ThreadedDevice`'s bounded queue, the serial-port hint both serial drivers
give, and the pluggable pty both emulators stand on."""

from __future__ import annotations

import contextlib
import errno
import os
import select
import stat
import threading
import time
from pathlib import Path

import pytest

from atemr.io.devices.base import QUEUE_SIZE, ThreadedDevice, serial_port_hint
from atemr.io.devices.pty_port import PluggablePty, PtyEmulator


# -- ThreadedDevice: the queue to the scheduler -----------------------------------------------------------------
class Burst(ThreadedDevice[int]):
    """A device whose first read returns ``n`` readings at once (faster than anyone drains them), then nothing."""

    def __init__(self, n: int, **kwargs) -> None:
        super().__init__("burst", now=time.monotonic, max_age_s=1.0, port="burst0", **kwargs)
        self.n = n
        self.reads = 0
        self.burst_handed_over = threading.Event()

    def _open(self) -> None:
        pass

    def _read(self) -> list[int]:
        self.reads += 1
        if self.reads == 1:
            return list(range(self.n))
        self.burst_handed_over.set()  # the first read's readings are all in the queue (or dropped)
        time.sleep(0.01)
        return []

    def _close(self) -> None:
        pass


def run_burst(device: Burst) -> list[int]:
    got: list[int] = []
    device.subscribe(got.append)
    device.start()
    try:
        assert device.burst_handed_over.wait(5.0), "the reader thread never read twice"
    finally:
        device.shutdown()
    device.tick(time.monotonic())
    return got


def test_a_stalled_scheduler_gets_only_the_newest_queue_size_readings():
    device = Burst(10, queue_size=3)
    assert device.queue_size == 3
    assert run_burst(device) == [7, 8, 9]
    assert device.dropped == 7 and device.count == 3 and device.latest == 9


def test_the_default_queue_holds_queue_size_readings():
    device = Burst(QUEUE_SIZE + 5)
    assert device.queue_size == QUEUE_SIZE
    assert run_burst(device) == list(range(5, QUEUE_SIZE + 5))
    assert device.dropped == 5


def test_a_queue_must_hold_a_reading():
    with pytest.raises(ValueError, match="queue_size must be at least 1"):
        Burst(1, queue_size=0)


# -- the serial-port hint ---------------------------------------------------------------------------------------
def hint(port: str, error: BaseException) -> str:
    return serial_port_hint("imu", port, error, device="the WT901", udev_name="/dev/imu")


def test_no_permission_points_at_the_dialout_group(tmp_path):
    port = str(tmp_path / "ttyUSB0")
    text = hint(port, PermissionError(errno.EACCES, "Permission denied"))
    assert text == (f"imu: no permission to open {port}: add the user to the dialout group "
                    f"(sudo usermod -aG dialout $USER, then log in again) ([Errno 13] Permission denied)")
    assert "dialout" in hint(port, OSError(errno.EPERM, "Operation not permitted"))


def test_a_missing_port_and_a_dangling_link_ask_whether_the_device_is_plugged_in(tmp_path):
    port = tmp_path / "imu"
    error = FileNotFoundError(errno.ENOENT, "No such file or directory")
    assert hint(str(port), error) == (f"imu: {port} does not exist: is the WT901 plugged in? "
                                      f"(ls /dev/ttyUSB*; a udev rule can name it /dev/imu)")
    port.symlink_to(tmp_path / "gone")
    assert f"{port} does not exist (a link to a device that is gone): is the WT901 plugged in?" in hint(
        str(port), error)


def test_a_port_that_exists_but_does_not_open_may_be_busy(tmp_path):
    port = tmp_path / "ttyUSB0"
    port.touch()
    text = hint(str(port), OSError(errno.EBUSY, "Device or resource busy"))
    assert text == f"imu: cannot open {port} ([Errno 16] Device or resource busy): is another program using it?"


# -- PluggablePty -------------------------------------------------------------------------------------------------
def hung_up(fd: int) -> bool:
    """Whether the pty a host holds open at ``fd`` has lost its device (reads fail or reach end of file)."""
    os.set_blocking(fd, False)
    try:
        return os.read(fd, 1) == b""
    except BlockingIOError:  # open, nothing to read
        return False
    except OSError:  # EIO: the device side is gone
        return True


def test_plug_points_the_link_at_a_raw_pty_the_emulator_writes_through_master():
    pty = PluggablePty("dev", prefix="atemr-test-")
    try:
        assert pty.port == str(pty.directory / "dev") and not pty.plugged and pty.master is None
        assert not os.path.lexists(pty.port)  # nothing plugged in yet
        pty.plug()
        assert pty.plugged and os.path.islink(pty.port)
        assert stat.S_ISCHR(os.stat(pty.port).st_mode)
        host = os.open(pty.port, os.O_RDWR | os.O_NOCTTY)
        try:
            with pty.lock:
                master = pty.master
                assert master is not None
                os.write(master, b"\x55\xaa\r\n")
            assert os.read(host, 16) == b"\x55\xaa\r\n"  # raw: no CR/LF translation, no echo
            os.write(host, b"cmd")
            time.sleep(0.05)
            assert os.read(master, 16) == b"cmd"
            with pytest.raises(BlockingIOError):  # the emulator's side never blocks
                os.read(master, 16)
        finally:
            os.close(host)
    finally:
        pty.close()


def test_unplug_removes_the_link_and_replug_points_it_at_a_new_pty_powered_on_under_the_lock():
    pty = PluggablePty("dev", prefix="atemr-test-")
    powered: list[bool] = []
    try:
        pty.plug(on_plug=lambda: powered.append(pty.lock.locked()))
        pty.unplug()
        assert not pty.plugged and pty.master is None and not os.path.lexists(pty.port)
        pty.unplug()  # idempotent
        pty.plug(on_plug=lambda: powered.append(pty.lock.locked()))
        host = os.open(pty.port, os.O_RDWR | os.O_NOCTTY)
        try:
            assert not hung_up(host)
            pty.plug()  # plugging while plugged in unplugs first: the host's pty is hung up
            assert hung_up(host)
        finally:
            os.close(host)
        assert pty.plugged and pty.master is not None and os.path.islink(pty.port)
        assert powered == [True, True]
        assert [p.name for p in pty.directory.iterdir()] == ["dev"]  # no temporary link left behind
    finally:
        pty.close()


def test_close_removes_its_own_directory_but_not_a_given_one(tmp_path):
    own = PluggablePty("dev", prefix="atemr-test-")
    own.plug()
    own.close()
    assert not own.directory.exists() and not own.plugged
    own.close()  # idempotent

    given = PluggablePty("lidar", directory=tmp_path)
    given.plug()
    assert Path(given.port).parent == tmp_path
    given.close()
    assert tmp_path.is_dir() and not os.path.lexists(given.port)


def test_a_failing_power_on_leaves_nothing_plugged_in():
    pty = PluggablePty("dev", prefix="atemr-test-")

    def broken() -> None:
        raise RuntimeError("no power")

    try:
        with pytest.raises(RuntimeError, match="no power"):
            pty.plug(on_plug=broken)
        assert not pty.plugged and not os.path.lexists(pty.port)
    finally:
        pty.close()


# -- PtyEmulator ----------------------------------------------------------------------------------------------
class Echo(PtyEmulator):
    """A device that sends back what it is sent, counting its power-ons."""

    def __init__(self, **kwargs) -> None:
        super().__init__("echo", prefix="atemr-test-", **kwargs)
        self.power_ons = 0

    def start(self) -> Echo:
        if self._thread is None:
            self.replug()
            self._start_thread("echo")
        return self

    def _power_on(self) -> None:
        self.power_ons += 1

    def _run(self) -> None:
        while not self._stop.is_set():
            with self._lock:
                master = self._pty.master
                if master is not None and select.select([master], [], [], 0.005)[0]:
                    with contextlib.suppress(BlockingIOError):
                        os.write(master, os.read(master, 64))
            self._stop.wait(0.001)


def echoed(port: str, data: bytes) -> bytes:
    host = os.open(port, os.O_RDWR | os.O_NOCTTY)
    try:
        os.write(host, data)
        assert select.select([host], [], [], 2.0)[0], "no answer"
        return os.read(host, 64)
    finally:
        os.close(host)


def test_an_emulator_plays_its_device_on_a_thread_until_closed(tmp_path):
    with Echo(directory=None) as emu:
        assert emu.plugged and emu.power_ons == 1 and emu.start() is emu  # started once
        assert echoed(emu.port, b"ping") == b"ping"
        thread = emu._thread
        emu.unplug()
        assert not emu.plugged and not os.path.lexists(emu.port)
        emu.replug()
        assert emu.power_ons == 2 and echoed(emu.port, b"again") == b"again"
        directory = Path(emu.port).parent
    assert thread is not None and not thread.is_alive()
    assert not emu.plugged and not directory.exists()
    emu.close()  # idempotent

    given = Echo(directory=tmp_path).start()
    given.close()
    assert tmp_path.is_dir() and not os.path.lexists(given.port)
